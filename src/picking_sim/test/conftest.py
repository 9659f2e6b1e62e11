from picking_planner.testing import pytest_configure  # noqa: F401  (hypothesis profiles, the fuzz marker)
