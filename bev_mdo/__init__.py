"""bev_mdo: distributed MDO of battery-electric-vehicle powertrains over ROS 2.

The Python API (docs/api.md) is ``bev_mdo.Study`` (= ``bev_mdo.api.Study``); it loads on first use,
so ``import bev_mdo`` stays cheap and imports no ROS.
"""

__version__ = "0.1.0"

_API = ("Study", "InputError", "ModelFailed", "Overrides", "Transport", "EvaluateResult", "OptimizeResult", "SweepResult",
        "SensitivityResult", "GlobalSensitivityResult", "ParetoResult")
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from bev_mdo import api

        return getattr(api, name)
    raise AttributeError(f"module 'bev_mdo' has no attribute {name!r}")
