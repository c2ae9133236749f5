"""Shared fixtures of the CLI tests."""
from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def sellar_raising(tmp_path) -> Path:
    """Sellar's MDF config with a discipline whose every point fails (test/data/user_modules: Raises)."""
    import yaml

    sellar = ROOT / "examples" / "sellar"
    raw = yaml.safe_load((sellar / "sellar_mdf.yaml").read_text())
    raw["search_path"] = [str(sellar), str(ROOT / "test" / "data" / "user_modules")]
    raw["disciplines"].append({"name": "raises", "class": "bad_disciplines:Raises"})
    cfg = tmp_path / "sellar.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    return cfg
