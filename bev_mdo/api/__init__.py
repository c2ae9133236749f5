"""The Python API of bev_mdo: load a config (a file or a mapping), change its problem, run it.

    from bev_mdo.api import Study
    study = Study("config/leaf_nedc.yaml").constrain("range_km", lower=250)
    result = study.optimize()
    result.x, result.objective, result.verdict, result.to_dict()

The CLI (``bev-mdo``) is a shell over the same functions; docs/api.md is the manual. Importing this
package is cheap: its parts (and numpy, scipy, rclpy) load on first use.
"""
from __future__ import annotations

import importlib

_PARTS = {
    "Study": "study", "InputError": "errors", "ModelFailed": "errors", "Overrides": "overrides", "Transport": "transport",
    "EvaluateResult": "results", "OptimizeResult": "results", "SweepResult": "results",
    "SensitivityResult": "results", "GlobalSensitivityResult": "results", "ParetoResult": "results",
}
__all__ = list(_PARTS)


def __getattr__(name: str):
    if name in _PARTS:
        return getattr(importlib.import_module(f"bev_mdo.api.{_PARTS[name]}"), name)
    raise AttributeError(f"module 'bev_mdo.api' has no attribute {name!r}")
