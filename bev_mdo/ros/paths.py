"""Where installed files live (config, share) for nodes started by hand."""
from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def default_config(name: str = "leaf_nedc.yaml") -> str:
    """A shipped run config (default: the default run config): the source tree's, else the installed
    share/bev_mdo/config copy."""
    local = REPO_ROOT / "config" / name
    if local.is_file():
        return str(local)
    try:
        from ament_index_python.packages import get_package_share_directory

        return str(Path(get_package_share_directory("bev_mdo")) / "config" / name)
    except Exception:  # no ament index: fall back to the source path (the error names it)
        return str(local)
