"""The Python cost of the ``--compose coordinator`` direct path without any DDS (issue 18): the six
discipline nodes, the coordinator's RosEvaluator and composed.Beside wired as in a run, but built
without rclpy (stub publishers that count nothing and must never publish), timing one MDA of one
design against the in-process evaluator (p10 over N MDAs, three rounds). It reaches into the
classes' internals (it sets the attributes their __init__ would), so it follows their changes.
No ROS lock needed (no participant is created).

  . scripts/env.sh && python bench/profile_beside_nodds.py [N] [prof] [micro]
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

if "micro" in sys.argv:
    import timeit
    from bev_mdo.ros import wire
    cap = {}
    real = ev._on_result
    def grab(msg, local=False):
        cap.setdefault(msg.discipline, msg)
        return real(msg, local=local)
    for nd in nodes:
        nd.local_coordinator = lambda m, local=True: grab(m, local)
    form.analyse(x)
    def T(label, f, k=20000):
        t = min(timeit.repeat(f, number=k, repeat=5)) / k * 1e6
        print(f"{label:50s} {t:7.2f} us")
    eng = nodes[1]
    msg = cap["energy"]
    T("wire.Result()", wire.Result)
    T("wire.Request()", lambda: wire.Request("r", 1, "", flow=names))
    T("wire.batch(4 cols)", lambda: wire.batch({"a": x[0][:1], "b": x[0][:1], "c": x[0][:1], "d": x[0][:1]}))
    T("from_named_array", lambda: wire.from_named_array(msg.outputs))
    T("node._for_me", lambda: eng._for_me(msg))
    T("node.publish_stats", lambda: eng.publish_stats())
    T("node._fill_header", lambda: eng._fill_header(wire.Result(), msg))
    T("put_point_errors", lambda: wire.put_point_errors(msg, {}))
    T("point_errors_of", lambda: wire.point_errors_of(msg, 1))
    from bev_mdo.mdo.discipline import run_discipline, all_finite
    from bev_mdo.ros.common import stamp
    T("stamp", lambda: stamp(msg.header))
    T("all_finite(1)", lambda: all_finite([msg.point_ok]))
    req = {"motor_kw": np.array([80.0]), "battery_kwh": np.array([40.0]), "gear_ratio": np.array([8.0])}
    vm = nodes[0]
    T("run_discipline(vehicle_mass)", lambda: run_discipline(vm.discipline, req))
    T("vm.discipline.compute", lambda: vm.discipline.compute(req))
    def on_result():
        ev._pending[(msg.evaluation_id, msg.discipline)] = P
        ev.ledger.answered.discard((msg.evaluation_id, msg.discipline))
        ev._on_result(msg, local=True)
    from bev_mdo.ros.evaluator import _Pending
    P = _Pending(0, "energy", wire.Request("harness", msg.evaluation_id, ""), 1, 0, flow=True)
    P.request.header.frame_id = msg.header.frame_id
    T("ev._on_result(local)", on_result)
    T("ledger pending set+discard only", lambda: (ev._pending.__setitem__((msg.evaluation_id, msg.discipline), P), ev.ledger.answered.discard(1)))
    T("publisher-count fake", lambda: eng._mda_pub.get_subscription_count())
    T("flow.rows_evaluated", lambda: flow.rows_evaluated(eng.source_of, {"vehicle_mass": ({}, np.ones(1, bool))}, 1))
    T("form.analyse in-process", lambda: ref.analyse(x), 2000)

