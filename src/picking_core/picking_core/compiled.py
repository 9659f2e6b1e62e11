"""Loading a kernel compiled with numba, which always has a numpy path to fall back on."""

from __future__ import annotations

import importlib
import warnings


def load(module, what, fallback):
    """The compiled ``module`` (an absolute name), or None: without numba, or, with a
    RuntimeWarning that names ``what`` did not load, why, and ``fallback`` (what answers
    instead), when numba cannot compile or cache it here (no writable cache directory, say).
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        return None
    except Exception as exc:  # noqa: BLE001 - numba's own errors: the numpy path answers
        warnings.warn(f'{what} did not load ({type(exc).__name__}: {exc}); {fallback}', RuntimeWarning,
                      stacklevel=3)
        return None
