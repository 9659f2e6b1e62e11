"""Shared test settings of the packages (imported by their conftest.py files).

Hypothesis profiles: ``default`` (60 examples a property: quick, for every test run)
and ``long`` (10 000: ``make fuzz``, i.e. ``pytest -m fuzz --hypothesis-profile=long``),
and the ``fuzz`` marker of the arbitrary-input tests.
"""

from hypothesis import HealthCheck, settings

_RELAXED = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
settings.register_profile('default', max_examples=60, deadline=None, suppress_health_check=_RELAXED)
settings.register_profile('long', max_examples=10_000, deadline=None, suppress_health_check=_RELAXED)


def pytest_configure(config):
    config.addinivalue_line('markers', 'fuzz: arbitrary input over a public function (long run: make fuzz)')
