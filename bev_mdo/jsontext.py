"""The text of every ``--json`` output and every JSON file bev_mdo writes (``answers.json``, ``front.json``,
``summary.json``, the bag's answers record): strict JSON (RFC 8259) that any parser reads.

Python's json writes NaN and Infinity as bare words, which are not JSON (jq, JavaScript, most
parsers refuse the whole document). A number that is not finite (a failed evaluation's outputs, a
margin of a failed point) is written as ``null`` instead; numpy numbers and arrays as their plain
values. Other objects are written as ``float(obj)``, as the commands did before.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any


def strict(obj: Any) -> Any:
    """``obj`` with every non-finite float replaced by None and numpy values made plain (recursively)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict(v) for v in obj]
    if type(obj).__module__ == "numpy":  # np.float64, np.bool_, np.int64, np.ndarray: no numpy import needed
        value = obj.tolist() if hasattr(obj, "tolist") else obj
        return value if value is obj else strict(value)
    return obj


def dumps(obj: Any, indent: int | None = 2) -> str:
    """Strict JSON text of ``obj``: non-finite numbers as null (never NaN or Infinity)."""
    return json.dumps(strict(obj), indent=indent, allow_nan=False, default=lambda o: strict(float(o)))


def write(path: str | Path, obj: Any) -> None:
    """Write ``obj`` to the file ``path`` as strict JSON (``dumps``), ending in a newline."""
    Path(path).write_text(dumps(obj) + "\n", encoding="utf-8")
