"""Sessions: the "start nodes, recorder, coordinator; run; stop" sequences, out of the CLI.

* ``OptimizeRosSession``: one optimisation over ROS (``bev-mdo optimize`` and ``resume``): discipline nodes (pools,
  composed processes) and a recorder started for the run, signed with a per-run key by default (docs/security.md),
  the config's baseline and the run coordinated in this process, every process stopped on exit (the recorder
  first) and what happened summarised.
* ``ParetoInProcessSession``/``ParetoRosSession``: the sessions of a multi-run study (``bev-mdo pareto``,
  bench/bench_pareto.py): where its evaluators come from and where its ParetoFront messages go: in-process
  evaluators and a bag written directly (BagSink), or over ROS a recorder for the whole session and one set of
  discipline nodes and one coordinator per topology.

Both ROS sessions prepare their run directory as launcher.OwnSuite does (launcher.prepare_run_dir: per-run key, the
resolved config written for the nodes and the recorder) and start the recorder with launcher.start_recorder. ROS is imported only when a
ROS session starts.
"""
from __future__ import annotations

import contextlib
import time
from pathlib import Path

from bev_mdo.config import RunConfig, plain
from bev_mdo.processes import beside_coordinator, plan_processes
from bev_mdo.ros_settings import participant_lease_s
from bev_mdo.stacks import teardown

ACK_GRACE_S = 1.0  # a live local recorder acknowledges in milliseconds (in DDS threads, not Python's)


def key_dir_for(bag: Path) -> Path:
    """Where a run's per-run key lives: ``<bag parent>/.keys/<bag name>`` (beside the bag, never in it). A key left
    there by an earlier run that never wrote this bag (it failed or was stopped before its recorder started) is stale:
    it is removed, so a re-run with the same ``--bag`` gets a fresh key instead of failing on the existing file."""
    from bev_mdo.bag.reader import holds_bag

    d = bag.parent / ".keys" / bag.name
    stale = d / "sign.key"
    if stale.is_file() and not holds_bag(bag):
        stale.unlink()
    return d


def analyse_baseline(config, evaluator=None) -> dict | None:
    """The config's ``problem.baseline`` analysed through ``evaluator`` (default: in process): {name, design,
    outputs, feasible, ...}; None when the config names no baseline. A failed analysis is reported in ``error``
    (with no outputs), never raised: the run's own result must not be lost to its baseline. ``notes`` (one line
    each) says what a table of its numbers does not: a design variable outside its bounds (infeasible whatever
    its constraints say, by the rule evaluate applies: mdo.active.outside_bounds) and a model parameter the
    baseline sets to other than the run's value."""
    from bev_mdo.mdo.driver import evaluate_design
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    config = RunConfig.of(config)
    base = config.baseline
    if not base:
        return None
    outside, notes = baseline_notes(config, base["design"])
    try:
        report = evaluate_design(config.settings, evaluator or InProcessEvaluator(config.timed_disciplines()), base["design"])
    except Exception as exc:  # noqa: BLE001 - reported beside the result
        report = {"design": dict(base["design"]), "outputs": {}, "feasible": False,
                  "ok": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    if outside:
        report["feasible"] = False
    return {"name": base["name"], **report, **({"notes": notes} if notes else {})}


def baseline_notes(config: RunConfig, design: dict) -> tuple[bool, list[str]]:
    """(whether ``design`` lies outside its bounds, the notes of ``analyse_baseline``)."""
    from bev_mdo.mdo.active import outside_bounds, outside_note
    from bev_mdo.mdo.driver import feasibility_tolerance

    tol, outside, notes = feasibility_tolerance(config.settings), False, []
    for d in config.problem.design_variables:
        v = design.get(d.name)
        if v is not None and outside_bounds(d, v, tol):  # the sentence evaluate writes for such a design
            outside = True
            notes.append(outside_note(d, v))
    run = {k: v for disc in config.disciplines for k, v in (getattr(disc, "parameters", None) or {}).items()}
    run.update(config.problem.parameters)  # the problem's own overrides are the run's values
    for k, v in design.items():  # a parameter the baseline sets changes its numbers: the table has no row for it
        if k not in config.problem.names:
            given = run.get(k)
            if isinstance(given, (int, float)) and float(given) != v:
                notes.append(f"{k} = {v:g} (the run's {float(given):g})")
            elif not isinstance(given, (int, float)):
                notes.append(f"{k} = {v:g} (set by the baseline)")
    return outside, notes


class OptimizeRosSession:
    """One optimisation over ROS, as ``bev-mdo optimize`` runs it::

        with OptimizeRosSession(config, ros, bag, run_id, record=True) as session:
            result, baseline = session.run(on_iteration=show)
        extra = session.summary()

    ``config`` is the run's resolved config (its ros section as the run states it), ``ros`` the
    effective ros section (config, flags and environment resolved: api/transport.ros_section).
    Entering writes ``<bag>/logs`` (node logs, the resolved config), keeps the per-run key beside the
    bag (``<bag parent>/.keys/<bag name>``, never inside it: a bag directory is what users share),
    starts the discipline nodes (a process each, or as ``compose`` says: several per process, or
    ``coordinator``: in this process; ``instances``: pools, a process per instance) and, with
    ``record``, the recorder; exiting stops them all, the recorder first, after
    it acknowledged everything."""

    def __init__(self, config: dict, ros: dict, bag: Path, run_id: str, *, record: bool = True,
                 instances: dict | None = None, compose: str | None = None):
        self.config, self.ros, self.bag, self.run_id = RunConfig.of(config), ros, Path(bag), run_id
        self.record, self.instances, self.compose = record, instances, compose
        self.logs = self.bag / "logs"  # node logs and the resolved config, beside the bag in the run's directory
        self.launcher = None
        self.recorder = 0
        self.recorder_binding = None
        self.stats: dict = {}
        self.published = 0  # iteration records the run sent (recorder_failure: the bag must hold them all)

    def __enter__(self) -> "OptimizeRosSession":
        from bev_mdo.launcher import Launcher, prepare_run_dir, start_recorder
        from bev_mdo.ros.client import apply_ros_environment
        from bev_mdo.binding import config_binding
        from bev_mdo.config.load import recorded_text
        from bev_mdo.ros_settings import ros_environment

        env = ros_environment(self.ros)
        apply_ros_environment(self.ros)
        names = list(self.config.names)
        plan = dict(run_id=self.run_id, instance=self.run_id[:8], instances=self.instances, compose=self.compose)
        plan_processes(names, "", **plan)  # a rejected --compose leaves nothing behind: checked before any file
        self.config, resolved = prepare_run_dir(self.config, self.logs, key_dir_for(self.bag))
        self.launcher = Launcher(env, log_dir=self.logs)
        try:
            for label, argv in plan_processes(names, str(resolved.resolve()), **plan):
                self.launcher.add(label, argv)
            if self.record:
                self.recorder = start_recorder(self.launcher, self.bag, resolved, self.run_id)
                self.recorder_binding = config_binding(recorded_text(resolved))
            self.launcher.supervise(watch_hangs=True)
        except BaseException:
            self.launcher.stop(first=("recorder",))
            raise
        return self

    def run(self, formulation=None, optimizer=None, x0=None, on_iteration=None, starts=1,
            seed=0) -> tuple[dict, dict | None]:
        """(result without its history, baseline) of the run; the coordinator runs in this process."""
        import rclpy

        from bev_mdo.ros import coordinator_node

        ctx = rclpy.context.Context()
        rclpy.init(context=ctx)
        beside = None

        def sent(rec: dict) -> None:  # called once the coordinator published the record
            self.published += 1
            return on_iteration(rec) if on_iteration is not None else None
        try:
            from bev_mdo.ros.composed import Beside

            local = beside_coordinator(self.compose, list(self.config.names), self.instances)
            if local:  # --compose coordinator: the disciplines' nodes in this process, served by its coordinator
                beside = Beside(self.config, local, ctx, run_id=self.run_id, instance=self.run_id[:8])
            # The baseline does not depend on the optimum: it is analysed BEFORE the optimisation, so the
            # end of the run evaluates nothing and never waits for a node that died late (a SIGKILLed
            # vehicle_mass after the optimiser's last evaluation stalled the baseline until its restart
            # was discovered: 8.5 s of tail in bench/bench_kill_tail.py). It goes through the run's own
            # node as the sub-run ``<run>-baseline``: no second node to discover, nor to tear down mid-run
            # (on a crowded host that teardown hung in the middleware past its bound).
            baseline = {}

            def analyse(evaluator) -> None:
                evaluator.recovering = self.launcher.recovering  # retries wait for a node being restarted
                with evaluator.sub_run("baseline"):
                    baseline["value"] = analyse_baseline(self.config, evaluator)

            res, stats = coordinator_node.run(self.config, run_id=self.run_id, formulation=formulation,
                                              optimizer=optimizer, x0=x0, on_iteration=sent,
                                              starts=starts, seed=seed,
                                              recorder_subscribers=self.recorder, context=ctx,
                                              recorder_binding=self.recorder_binding, starting=self.launcher.progress,
                                              instances=self.instances, beside=beside, before=analyse,
                                              give_up_acks=acks_needless(self.launcher) if self.recorder else None,
                                              recorder_gone=recorder_gone(self.launcher) if self.recorder else None)
            stats["t_acked"] = time.monotonic()  # the final acknowledgements are in (or given up)
            self.stats = stats
            out = res.summary()
            return out, baseline.get("value")
        finally:
            def close():
                if beside is not None:
                    beside.close()
                rclpy.shutdown(context=ctx)

            # bounded (a participant hung in the middleware would block here for good); in the CLI left for the
            # exit, after the result is printed (a composed node's destroy_node hung there under load)
            teardown(close)

    def __exit__(self, *exc) -> None:
        self.launcher.stop(first=("recorder",))
        self.t_end = time.monotonic()

    def summary(self) -> dict:
        """What the finished run did, for the CLI's result: ids, bag, drops, retries, restarts, signing,
        the tail after the optimiser, pools, first errors, a recorder that died."""
        stats = self.stats
        tail_s = self.t_end - stats["t_optimised"]  # after the optimiser: final acknowledgements, shutdown
        tail = {"acks_s": stats["t_acked"] - stats["t_optimised"], "shutdown_s": self.t_end - stats["t_acked"]}
        restarts = {n.label: n.restarts for n in self.launcher.nodes if n.restarts}
        sent = {"/bev_mdo/iteration": self.published}
        recorder_failed = recorder_failure(self.launcher, self.bag, sent) if self.recorder else None
        extra = {"transport": "ros", "run_id": self.run_id, "domain_id": self.ros["domain_id"],
                 "bag": str(self.bag) if self.record else None, "logs": str(self.logs),
                 "dropped_messages": stats["dropped"], "retried_requests": stats["retried"],
                 "node_restarts": restarts, "refused_instances": stats.get("refused_instances", {}),
                 "signing": _signing(self.ros, self.config), "tail_s": round(tail_s, 3),
                 "tail_parts_s": {k: round(v, 3) for k, v in tail.items()}}
        hangs = {n.label: n.hangs for n in self.launcher.nodes if n.hangs}
        if hangs:  # restarted by the watchdog: alive but silent on the ROS graph (ros/watchdog.py)
            extra["node_hangs"] = hangs
        if stats.get("pools"):
            extra["pools"] = stats["pools"]  # per-instance work, throughput and failures (pool.py)
        if stats.get("discipline_errors"):
            extra["discipline_errors"] = stats["discipline_errors"]
        if stats.get("unresponsive"):  # stopped answering: the CLI warns and exits 4
            extra["unresponsive_disciplines"] = stats["unresponsive"]
        if recorder_failed:
            extra["recorder_failed"] = recorder_failed
        return extra


def acks_needless(launcher):
    """When the coordinator's final wait for acknowledgements may end early (they are awaited only so the recorder
    misses nothing): at once when the recorder died, and after ACK_GRACE_S when a node died within the last lease,
    because a killed reader never acknowledges and is matched until its participant lease expires (the lease of
    the Fast DDS profile in use: ros_settings.participant_lease_s)."""
    lease_s = participant_lease_s()
    started = []

    def needless() -> bool:
        if launcher.node("recorder").died is not None:
            return True
        now = time.monotonic()
        started[:] = started or [now]
        return now - started[0] >= ACK_GRACE_S and launcher.died_within(lease_s + ACK_GRACE_S)

    return needless


def recorder_gone(launcher):
    """For the start-up waits for the run's recorder: None while its process runs, else why it is gone (its exit
    status and the last error line of its log), so the run stops at once rather than wait for its declaration."""
    def why() -> str | None:
        node = launcher.node("recorder")
        if node.died is None:
            return None
        lines = [ln.strip() for ln in _tail(node.log_path).splitlines() if ln.strip()]
        said = next((ln for ln in reversed(lines) if "error" in ln.lower()), lines[-1] if lines else "")
        return (f"exited with {node.died} during start-up" + (f": {said}" if said else "")
                + (f" (its log: {node.log_path})" if node.log_path else ""))

    return why


def _tail(path, size: int = 8192) -> str:
    """The end of a log file ('' if there is none)."""
    try:
        with open(path, "rb") as f:
            f.seek(max(0, f.seek(0, 2) - size))
            return f.read().decode("utf-8", "replace")
    except (OSError, TypeError):
        return ""


SENT_NOUNS = {"/bev_mdo/iteration": "iteration records", "/bev_mdo/pareto_front": "Pareto fronts"}


def recorder_failure(launcher, bag: Path, sent: dict | None = None) -> str | None:
    """None if the recorder lived to the end, or closed its bag and was then killed in its ROS teardown (past
    Launcher.stop's wait), and the bag holds all the run ``sent`` ({topic: messages the run published}); else a
    one-line warning, after making the bag readable again (summary and metadata rebuilt). What the bag holds
    decides, not when the supervisor saw the recorder end: one stopped during the run (a SIGTERM) that was still
    draining, closing its bag or in its teardown when the run ended was never seen to end during the run, and
    exited 0 to Launcher.stop's SIGINT as if it had recorded everything."""
    node = launcher.node("recorder")
    during = node.died is not None  # ended during the run (the supervisor saw it): failed, even SIGTERMed (exit 143)
    status = node.died if during else (node.proc.returncode if node.proc is not None else None)
    told = status in (0, 130, 143)  # it took SIGINT or SIGTERM and closed its bag (ros/recorder_node.main)
    if not during and (told or status is None) and not short_of(bag, sent):
        return None
    note = (f"the recorder {'stopped' if told else 'died'} (exit status {status}) during the run" if not node.frozen else
            "the recorder was frozen (its process stopped, e.g. by SIGSTOP) at the end of the run and was killed")
    note += "; the bag holds only what it recorded before"
    try:
        from bev_mdo.bag.reader import find_mcap
        from bev_mdo.bag.repair import repair
        closed = (find_mcap(bag).parent / "metadata.yaml").is_file()  # written last by the recorder's close
        res = repair(bag)
        whole = closed and not res.was_truncated
        short = short_of(bag, sent)  # as the recorder's (or the repair's) metadata.yaml counts them
        if whole and not during and not short:  # the bag holds everything: nothing failed
            return None
        if short and not during and not node.frozen:  # never seen to end during the run: its bag says it did
            note = f"the recorder stopped recording before the run ended (exit status {status}); the bag holds {short}"
        elif short:
            note += f": {short}"
        note += f" ({res.message_count} messages, {'closed by the recorder' if whole else 'summary and metadata rebuilt'})"
    except (ValueError, OSError) as exc:
        note += f"; the bag could not be repaired: {exc}"
    return note


def short_of(bag: Path, sent: dict | None) -> str:
    """'' or what the bag lacks of what the run ``sent`` ({topic: messages published}), as the metadata.yaml that
    describes it counts them ('265 of the 852 iteration records the run published'; '' without one)."""
    from bev_mdo.bag.reader import bagfile_information, find_mcap

    try:
        topics = bagfile_information(find_mcap(bag).parent).get("topics_with_message_count") or []
        held = {t["topic_metadata"]["name"]: int(t["message_count"]) for t in topics}
    except (ValueError, OSError, TypeError, KeyError):
        return ""
    return "; ".join(f"{held.get(t, 0)} of the {n} {SENT_NOUNS.get(t, 'messages on ' + t)} the run published"
                     for t, n in (sent or {}).items() if held and held.get(t, 0) < n)


def _signing(ros: dict, config: RunConfig) -> str:
    """How this run's messages were signed, for the summary."""
    if ros.get("sign_key_file"):
        return f"key file {ros['sign_key_file']}"
    return "per-run key" if config.ros.get("sign_key_file") else "off (ros.signing: false)"


class ParetoInProcessSession:
    """In process: the fronts go straight into ``<out>/bag`` (BagWriter)."""

    def __init__(self, raw, bag: Path, run_id: str):
        import yaml

        from bev_mdo.ros.pareto_publisher import BagSink

        self.sink = BagSink(bag, {"run_id": run_id, "config_yaml": yaml.safe_dump(plain(raw), sort_keys=False)})
        self.stats = {}

    def evaluator(self, cfg, topology):
        """The in-process evaluator of one topology, closed on exit."""
        from bev_mdo.mdo.evaluator import InProcessEvaluator

        return contextlib.closing(InProcessEvaluator(RunConfig.of(cfg).timed_disciplines()))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.sink.close()


class ParetoRosSession:
    """Over ROS, as ``bev-mdo optimize`` does it: a recorder node writing ``<out>/bag`` for the
    whole run, one set of discipline nodes per topology (the previous set is stopped first: the
    nodes of two topologies answer the same topics), a coordinator (its RosEvaluator) per topology
    and one ParetoFront publisher; the recorder is stopped first, after it acknowledged every front."""

    def __init__(self, raw, ros: dict, out: Path, bag: Path, run_id: str, instances: dict | None = None):
        self.raw, self.ros, self.out, self.bag, self.run_id = raw, dict(ros), out, bag, run_id
        self.instances = {k: v for k, v in (instances or {}).items() if v > 1}  # pools (--instances), as optimize
        self.stats = {"dropped_messages": {}, "retried_requests": 0}
        self.labels: list[str] = []
        self.launcher = self.ctx = self.sink = None
        self.recorder = 0

    def __enter__(self):
        import rclpy

        from bev_mdo.protocol.signing import Signer
        from bev_mdo.ros.client import apply_ros_environment
        from bev_mdo.ros.coordinator_node import node_name_for
        from bev_mdo.launcher import Launcher, prepare_run_dir, start_recorder
        from bev_mdo.ros.pareto_publisher import RosSink
        from bev_mdo.binding import config_binding
        from bev_mdo.config.load import recorded_text
        from bev_mdo.ros_settings import ros_environment

        apply_ros_environment(self.ros)
        self.logs = self.out / ".logs"
        # signed by default (docs/security.md); the key stays in the study's own .logs
        signed, resolved = prepare_run_dir({**self.raw, "ros": self.ros}, self.logs, self.logs)
        self.ros = signed["ros"]
        self.launcher = Launcher(ros_environment(self.ros), log_dir=self.logs)
        self._acks_needless = acks_needless(self.launcher)
        try:
            self.recorder = start_recorder(self.launcher, self.bag, resolved, self.run_id)
            self.binding = config_binding(recorded_text(resolved))
            self.launcher.supervise(watch_hangs=True)
            self.ctx = rclpy.context.Context()
            rclpy.init(context=self.ctx)
            self.sink = RosSink(self.ctx, self.run_id, node_name_for(self.run_id, "pareto_publisher"),
                                Signer.from_ros(self.ros), self.binding)
            self.sink.wait_for_recorder(self.ros["discovery_wait_s"], recorder_gone(self.launcher))
        except BaseException:
            self.__exit__()
            raise
        return self

    @contextlib.contextmanager
    def evaluator(self, cfg, topology):
        from bev_mdo.launcher import prepare_run_dir
        from bev_mdo.ros import coordinator_node

        cfg = RunConfig.of(cfg).with_ros(self.ros)
        wait_s = self.ros["discovery_wait_s"]
        names = list(cfg.names)
        self._stop_disciplines(names, wait_s)
        cfg, resolved = prepare_run_dir(cfg, self.logs / topology, self.logs)  # signed already: the session's key
        sub_run = f"{self.run_id}-{topology}"
        for label, argv in plan_processes(names, str(resolved.resolve()), run_id=sub_run, instances=self.instances):
            self.launcher.add(f"{topology}/{label}", argv)
            self.labels.append(f"{topology}/{label}")
        node = coordinator_node.CoordinatorNode(cfg, sub_run, context=self.ctx,
                                                node_name=coordinator_node.node_name_for(sub_run))
        node.evaluator.starting = self.launcher.progress
        node.evaluator.recovering = self.launcher.recovering  # retries wait for a node being restarted
        # a recorder that died in an earlier topology is not waited for (the study goes on, reported at the end)
        recorders = self.recorder if self.launcher.node("recorder").died is None else 0
        try:
            node.evaluator.wait_for_disciplines(names, wait_s)
            for name, count in self.instances.items():  # a pool starts with all its instances (pool.py)
                node.evaluator.wait_for_instances(name, count, wait_s)
            if recorders:  # the study's recorder, by its declaration: it matched every topic of these nodes
                node.wait_for_recorder(wait_s, self.binding, recorder_gone(self.launcher))
            node.evaluator.warm_up(names)
            yield node.evaluator
            for k, v in node.evaluator.dropped.items():
                self.stats["dropped_messages"][k] = self.stats["dropped_messages"].get(k, 0) + v
            self.stats["retried_requests"] += node.evaluator.retried
            # the recorder has every request of this topology and every front so far (unless it died)
            node.wait_for_all_acked(wait_s, give_up=self._acks_needless)
            self.sink.wait_for_all_acked(wait_s, give_up=self._acks_needless)
        finally:
            node.evaluator.close()
            node.destroy_node()

    def _stop_disciplines(self, names, wait_s: float) -> None:
        """Stop the previous topology's discipline nodes and wait until the graph lost them."""
        for label in self.labels:
            self.launcher.remove(label)
        self.labels = []
        from bev_mdo.ros.fastwait import until

        node_names = {f"{n}_node" for n in names}
        if not until(lambda: not any(g.startswith(n) for g in self.sink.node.get_node_names() for n in node_names),
                     wait_s, lambda: self.sink.spin(0.02)):  # graph polling
            raise ValueError(f"discipline nodes of the previous topology still on the graph after {wait_s:g} s")

    def __exit__(self, *exc):
        import rclpy

        try:
            if self.sink is not None:
                self.sink.wait_for_all_acked(self.ros["discovery_wait_s"], give_up=self._acks_needless)
            sink, ctx = self.sink, self.ctx

            def close():
                if sink is not None:
                    sink.close()
                if ctx is not None:
                    rclpy.shutdown(context=ctx)

            teardown(close)  # bounded; in the CLI left for the exit, after the fronts are written
        finally:
            if self.launcher is not None:
                self.launcher.stop(first=("recorder",))
                sent = {"/bev_mdo/pareto_front": self.sink.published} if self.sink is not None else None
                failed = recorder_failure(self.launcher, self.bag, sent) if self.recorder else None
                if failed:  # the CLI warns and exits 3, as optimize does
                    self.stats["recorder_failed"] = failed
                self.stats["node_restarts"] = {n.label: n.restarts for n in self.launcher.nodes if n.restarts}
                hangs = {n.label: n.hangs for n in self.launcher.nodes if n.hangs}
                if hangs:  # restarted by the watchdog (ros/watchdog.py)
                    self.stats["node_hangs"] = hangs
