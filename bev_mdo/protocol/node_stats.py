"""A discipline node's counters (``/bev_mdo/node_stats``: a std_msgs/String of JSON) and the row
``bev-mdo status`` makes of them. Each process sends its own: where it runs (host, pid), the run it is
bound to and its configuration fingerprint, so two processes given one node name (and one declaration
slot: /bev_mdo/discipline_info is kept per instance name) still show each its own. No ROS import.
"""
from __future__ import annotations

import json
import os
import socket


def payload(discipline: str, instance: str, counts: dict, run_id: str, fingerprint: str, compute_s: float) -> str:
    """The JSON text a node publishes: its counters, its run ("" unbound; a run's recorder keeps its own
    run's only), its fingerprint, and for ``bev-mdo status`` where it runs and how long it computed."""
    return json.dumps({"discipline": discipline, "instance": instance, "counts": counts, "run_id": run_id,
                       "fingerprint": fingerprint, "host": socket.gethostname(), "pid": os.getpid(),
                       "compute_s": round(compute_s, 6)}, sort_keys=True)


def status_row(discipline: str, instance: str, live: bool, info, first: dict | None, last: dict | None,
               listen_s: float) -> dict:
    """One ``bev-mdo status`` row: an instance's declaration `info` (a DisciplineInfo, or None) and the first
    and last counters one of its processes sent while status listened (None: it sent none). The run and the
    fingerprint are the process's own counters' when they name them (the declaration is the last one sent
    under the instance name, maybe another process's), else the declaration's."""
    s1, s0 = last or {}, first or {}
    c1, c0 = s1.get("counts", {}), s0.get("counts", {})
    points = int(c1.get("points", 0))
    compute_s = float(s1.get("compute_s", 0.0))
    own = "fingerprint" in s1  # a node of an older version sends neither its run nor its fingerprint
    run_id = s1.get("run_id") if own else info.run_id if info else None
    return {
        "discipline": discipline, "instance": instance, "live": live,
        "host": s1.get("host", "?"), "pid": s1.get("pid"),
        "run_id": "?" if run_id is None else (run_id or "standalone"),
        "fingerprint": s1["fingerprint"] if own else info.fingerprint if info else "?",
        "points": points, "answered": int(c1.get("answered", 0)),
        "rejected": int(c1.get("rejected", 0)), "compute_s": compute_s,
        "capacity_points_per_s": round(points / compute_s, 1) if compute_s > 0 else None,
        "recent_points_per_s": (round((points - int(c0.get("points", 0))) / listen_s, 1)
                                if last is not None else None),  # None: it sent no counters
    }
