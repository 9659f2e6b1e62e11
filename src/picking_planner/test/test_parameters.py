"""The planner node's parameter table: every default is a setting the planning core accepts."""

from picking_core.kinematics import ArmModel
from picking_core.pick_cycle import PickSettings
from picking_core.planning import PlannerSettings
from picking_description import default_urdf
from picking_planner.parameters import PARAMS, PICK, SETTINGS


def test_the_defaults_are_settings_the_core_plans_with():
    defaults = {p.name: p.default for p in PARAMS}
    PlannerSettings(**{n: defaults[n] for n in SETTINGS}).validate()
    PickSettings(**{n: tuple(defaults[n]) if isinstance(defaults[n], list) else defaults[n] for n in PICK}).validate(
        ArmModel.from_urdf(default_urdf()))


def test_every_parameter_is_described_with_its_unit():
    for p in PARAMS:
        assert p.description and p.describe().endswith('.'), p.name
        if p.range is not None:
            assert p.range[0] <= p.default <= p.range[1], p.name
