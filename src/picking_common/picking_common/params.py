"""Parameters that tell the truth: each node's parameters as a table of :class:`Param` (default,
description with units, range, read-only), declared with ROS parameter descriptors, so that
``ros2 param describe`` shows them, ``ros2 param set`` is refused with the reason for a read-only one
or a value out of range, and a parameter file's unknown key is reported at start. The tables also
write ``docs/parameters.md`` (``tools/param_docs.py``, ``make docs``)."""

from __future__ import annotations

from dataclasses import dataclass

#: Parameters every rclpy node has or that ROS tools set on any node: never "unknown".
_ROS_OWN = ('use_sim_time', 'start_type_description_service')


@dataclass(frozen=True)
class Param:
    """One ROS parameter of a node."""

    name: str
    default: object
    description: str
    unit: str = ''                     # SI: 'm', 's', 'Hz', 'rad', 'rad/s', ... ('' for none)
    range: tuple = None                # (lowest, highest), inclusive; checked by ROS on every set
    read_only: bool = False            # fixed once the node runs (set it at start: -p, a params file)

    def describe(self):
        """The descriptor's description: the text, its unit and what setting it does."""
        unit = f' [{self.unit}]' if self.unit else ''
        when = ' Read-only: set it at start.' if self.read_only else ''
        return f'{self.description}{unit}.{when}'


def descriptor(param):
    """The rcl_interfaces ParameterDescriptor of ``param``."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    out = ParameterDescriptor(name=param.name, description=param.describe(), read_only=param.read_only)
    if param.range is not None:
        lo, hi = param.range
        if isinstance(param.default, bool):
            raise ValueError(f'{param.name}: a boolean has no range')
        if isinstance(param.default, int):
            out.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
        else:
            out.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)]
    return out


def declare(node, params, check_unknown=True, others=()):
    """Declare ``params`` on ``node`` with their descriptors; returns their values by name.

    A value out of range or of the wrong type (given with -p or a params file) raises ValueError
    with the parameter's name. Keys given for this node that neither ``params`` nor ``others``
    (declared by an earlier call) name are reported as a warning, unless ``check_unknown`` is
    False (more parameters are declared after this call): a mistyped key would otherwise be
    ignored without a word.
    """
    from rclpy.exceptions import ParameterException
    values = {}
    for p in params:
        try:
            values[p.name] = node.declare_parameter(p.name, p.default, descriptor(p)).value
        except (ParameterException, TypeError) as exc:
            raise ValueError(f'parameter {p.name}: {exc}') from None
    if not check_unknown:
        return values
    known = {p.name for p in params} | set(others) | set(_ROS_OWN)
    unknown = sorted(n for n in getattr(node, '_parameter_overrides', {})
                     if n not in known and not n.startswith('qos_overrides.'))
    if unknown:
        node.get_logger().warning(f'unknown parameters given for this node, ignored: {", ".join(unknown)} '
                                  f'(its parameters: {", ".join([*others, *(p.name for p in params)])})')
    return values


def markdown(params, shipped=None):
    """A Markdown table of ``params``: name, default, the value in the shipped file ``shipped``
    (a dict, when given), unit, range, read-only, description."""
    def show(v):
        if isinstance(v, bool):
            return str(v).lower()
        if isinstance(v, (list, tuple)):
            return '[' + ', '.join(show(x) for x in v) + ']'
        return f'`{v!r}`' if isinstance(v, str) else f'{v:g}' if isinstance(v, float) else str(v)
    head = ['parameter', 'default'] + (['shipped'] if shipped is not None else []) + \
        ['unit', 'range', 'read-only', 'description']
    rows = ['| ' + ' | '.join(head) + ' |', '|' + ' --- |' * len(head)]
    for p in params:
        cells = [f'`{p.name}`', show(p.default)]
        if shipped is not None:
            cells.append(show(shipped[p.name]) if p.name in shipped else '')
        rng = '' if p.range is None else f'{show(p.range[0])} to {show(p.range[1])}'
        cells += [p.unit, rng, 'yes' if p.read_only else '', p.description.replace('|', '\\|')]
        rows.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(rows)


def usage(prog, doc, params):
    """``--help`` of a node: how to run it, what it does (``doc``), and its parameters."""
    lines = [f'usage: {prog} [-h] [--ros-args [-r __ns:=/NAMESPACE] [-p NAME:=VALUE ...] [--params-file FILE ...]]',
             '', doc.strip(), '', 'parameters (-p NAME:=VALUE, or a --params-file; docs/parameters.md):']
    for p in params:
        default = p.default if not isinstance(p.default, str) else repr(p.default)
        rng = f', {p.range[0]:g} to {p.range[1]:g}' if p.range is not None else ''
        lines.append(f'  {p.name} = {default}{" " + p.unit if p.unit else ""}{rng}'
                     f'{" (read-only)" if p.read_only else ""}: {p.description}')
    return '\n'.join(lines)
