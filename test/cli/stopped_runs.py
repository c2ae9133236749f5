"""An in-process optimisation stopped after a given number of iteration records, as a Ctrl-C would stop
it (no end-of-run answers stored): the interrupted bags that the resume tests go on from."""
from __future__ import annotations

from pathlib import Path

import pytest


class Stop(KeyboardInterrupt):
    """What a Ctrl-C does to the run, raised after a record is written."""


def interrupted_run(config: Path, bag: Path, after: int, **options) -> None:
    """Run ``config`` in process into ``bag`` (OptimizeOptions ``options``, e.g. starts, seed) and stop it
    once ``after`` records are written."""
    from bev_mdo.api import optimize
    from bev_mdo.config import RunConfig

    opts = optimize.OptimizeOptions(transport="inprocess", bag=str(bag), quiet=True, **options)
    seen = []

    def stop(rec):
        seen.append(rec)
        if len(seen) == after:
            raise Stop

    with pytest.raises(Stop):
        optimize.run(RunConfig.load(config), opts, callback=stop)
