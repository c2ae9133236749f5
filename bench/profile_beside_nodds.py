"""The Python cost of the ``--compose coordinator`` direct path without any DDS (issue 18): the six
discipline nodes, the coordinator's RosEvaluator and composed.Beside wired as in a run, but built
without rclpy (stub publishers that count nothing and must never publish), timing one MDA of one
design against the in-process evaluator (p10 over N MDAs, three rounds). It reaches into the
classes' internals (it sets the attributes their __init__ would), so it follows their changes.
No ROS lock needed (no participant is created).

  . scripts/env.sh && python bench/profile_beside_nodds.py [N] [prof]
  (HARNESS_REPO=<a copy of the tree> to time another version)
"""
import sys, time, os, cProfile, pstats
from collections import Counter
from pathlib import Path
sys.path.insert(0, os.environ.get("HARNESS_REPO", str(Path(__file__).resolve().parents[1])))
import numpy as np
from bev_mdo.config import load_config, resolve_disciplines, run_settings
from bev_mdo.mdo import flow
from bev_mdo.mdo.discipline import readable
from bev_mdo.mdo.driver import build_formulation
from bev_mdo.mdo.evaluator import InProcessEvaluator, DisciplineSpec
from bev_mdo.mdo.ledger import Ledger
from bev_mdo.ros import binding
from bev_mdo.ros.discipline_node import DisciplineNode, _build
from bev_mdo.ros.evaluator import RosEvaluator
from bev_mdo.ros.composed import Beside, link_local
from bev_mdo.ros.common import MDA_REQUEST_TOPIC, request_topic, RESULT_TOPIC, mda_result_topic


class Pub:
    def __init__(self, topic, count):
        self.topic_name, self.count = topic, count
    def get_subscription_count(self):
        return self.count
    def publish(self, data):
        raise AssertionError("published")


class Sub:
    def __init__(self, topic):
        self.topic_name = topic
        self.callback = None


config = load_config(os.environ.get("HARNESS_REPO", str(Path(__file__).resolve().parents[1])) + "/config/leaf_nedc.yaml")
config = {**config, "ros": {**(config.get("ros") or {}), "signing": False}}
names = [d.name for d in resolve_disciplines(config)]
run_id = "harness"
nodes = []
for name in names:
    nd = DisciplineNode.__new__(DisciplineNode)
    nd.discipline, producer = _build(config, name)
    nd.discipline_name = name
    nd.bound_run = run_id
    nd.fingerprint, nd.effective_config = binding.fingerprint(config, name)
    nd.source_of = flow.sources_of(nd.discipline.inputs, producer, name)
    nd._allowed = readable(nd.discipline)
    nd.instance = f"/{name}_node"
    nd.counts = Counter()
    nd.compute_s = 0.0
    nd.signer = None
    nd._stats_sent, nd._stats_t = None, 0.0
    nd._result_pub = Pub(RESULT_TOPIC, 1)
    nd._sub = Sub(request_topic(name))
    nd._mda_pub = Pub(mda_result_topic(name), 1)
    nd._mda_sub = None if nd.source_of else Sub(MDA_REQUEST_TOPIC)
    nd._outputs_of = {s: {v for v, p in producer.items() if p == s} for s in set(nd.source_of.values())}
    nd._source_subs = {s: Sub(mda_result_topic(s)) for s in sorted(set(nd.source_of.values()))}
    nd._join = flow.FlowJoin(nd.source_of, nd._outputs_of, 64)
    nd.local_consumers, nd.local_sources = [], set()
    nd.local_coordinator, nd.local_readers = None, {}
    nd.publish_stats = (lambda *a, **k: None) if os.environ.get("NOSTATS") else DisciplineNode.publish_stats.__get__(nd)
    nd._stats_pub = Pub("/stats", 0); nd._stats_pub.publish = lambda m: None
    nodes.append(nd)
link_local(nodes)
for nd in nodes:
    nd._mda_pub.count = 1 + len(nd.local_consumers)

ev = RosEvaluator.__new__(RosEvaluator)
ev.signer = None
ev._config = config
ev.expected, ev._tags, ev.instances, ev.refused, ev.first_errors = {}, {}, {n: {f"{n}_node"} for n in names}, {}, {}
ev.accepted = []
ev.run_id = run_id
ev.timeout_s, ev.retries = 5.0, 3
ev.counts = Counter()
ev.ledger = Ledger(lambda p: p.request.header.frame_id)
ev.dropped = ev.ledger.dropped
ev.retried, ev.iteration, ev.unresponsive, ev.last_latency_s, ev._seq = 0, 0, set(), 0.0, 0
ev._pending = ev.ledger.pending
ev._results, ev._publishers = {}, {}
ev.flows, ev._flow_plans = 0, {}
ev._flow_pub = Pub(MDA_REQUEST_TOPIC, 3)
ev._flow_subs = {n: Sub(mda_result_topic(n)) for n in names}
ev.pool_mode, ev.pools = "share", {}
ev._parts, ev._batches, ev._flow_got, ev._flow_meta, ev.flow_shares = {}, {}, {}, {}, 0
ev.pool_data_flow, ev.pool_min_rows = True, 1
ev._info_t = float("inf")
ev._hot = []
ev.local_requests = None
ev.specs = {}
ev.coupling_sources = {}
for nd in nodes:
    d = nd.discipline
    ev.specs[nd.discipline_name] = DisciplineSpec(nd.discipline_name, tuple(d.inputs), tuple(d.outputs),
                                                  dict.fromkeys(getattr(d, "parameters", {}) or {}, float("nan")))
    ev.coupling_sources[nd.discipline_name] = dict(nd.source_of)


beside = Beside.__new__(Beside)
beside.nodes = nodes
beside._pairs, beside._evaluator = [], None
if hasattr(Beside, "_flow"):  # the whole-MDA direct path (issue 18, branch i18e)
    beside._engine = InProcessEvaluator(nd.discipline for nd in nodes)
    beside._flows, beside._bound = {}, set()
for nd in nodes:
    nd.hot_subscriptions = lambda: []
beside.attach(ev)

form = build_formulation(run_settings(config), ev)
ref = build_formulation(run_settings(config), InProcessEvaluator(resolve_disciplines(config)))
x = form.x0[None, :]
a, b = form.analyse(x), ref.analyse(x)
print("flows", ev.flows, "dropped", dict(ev.dropped))
N = int(sys.argv[1]) if len(sys.argv) > 1 else 3000


def p50(f):
    for _ in range(300):
        f.analyse(x)
    lat = []
    for _ in range(N):
        t0 = time.perf_counter(); f.analyse(x); lat.append(time.perf_counter() - t0)
    return np.percentile(lat, 10) * 1e6


for r in range(3):
    print(f"beside(no DDS) p10 {p50(form):.0f} us   in-process p10 {p50(ref):.0f} us")
if "prof" in sys.argv:
    pr = cProfile.Profile(); pr.enable()
    for _ in range(N): form.analyse(x)
    pr.disable()
    pstats.Stats(pr).sort_stats("tottime").print_stats(35)
