from picking_core.testing import pytest_configure  # noqa: F401  (hypothesis profiles, the fuzz marker)
