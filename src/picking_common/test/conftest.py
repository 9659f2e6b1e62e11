from picking_common.testing import pytest_configure  # noqa: F401  (hypothesis profiles, the fuzz marker)
