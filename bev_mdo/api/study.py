"""``Study``: a config (a YAML file or a mapping built in code), the changes made to its problem, and
the runs: evaluate, optimize, sweep (a DOE, grid or list), local and global sensitivity, pareto.
Every run goes through the same functions as the ``bev-mdo`` command of the same name; bad input
raises InputError with the line that command prints."""
from __future__ import annotations

import copy
import functools
import inspect
import math
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any, Mapping

from bev_mdo.api.errors import InputError
from bev_mdo.api.overrides import Overrides, real_number
from bev_mdo.api.results import (EvaluateResult, GlobalSensitivityResult, OptimizeResult, ParetoResult,
                                 SensitivityResult, SweepResult)
from bev_mdo.api.transport import DEFAULT_TRANSPORT, TRANSPORTS, Transport


def _input_errors(method):
    """A user's mistake (ValueError, a missing file) leaves as InputError with the CLI's one line; so does an
    argument the method does not have (a TypeError with no hint, where optimize's said 'did you mean')."""
    params = [p for p in inspect.signature(method).parameters.values() if p.name != "self"]
    known = [p.name for p in params if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)]

    @functools.wraps(method)
    def call(*args, **kwargs):
        if not any(p.kind is p.VAR_KEYWORD for p in params) and (wrong := [k for k in kwargs if k not in known]):
            from bev_mdo.mdo.vectors import did_you_mean

            raise InputError(f"{method.__name__}() has no argument {wrong[0]!r}; {did_you_mean(wrong[0], known)}"
                             f"its arguments: {', '.join(known)}")
        try:
            return method(*args, **kwargs)
        except InputError:
            raise
        except (ValueError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
            text = str(exc).strip()
            raise InputError(text.splitlines()[0] if text else type(exc).__name__) from exc
    return call


def _bag_notes(method):
    """A run that Ctrl-C stops raises its KeyboardInterrupt on (a library's caller decides), noted with the lines
    the CLI prints then (interrupts.interrupted_lines): what the run's bag holds and how to go on from it."""
    @functools.wraps(method)
    def call(*args, **kwargs):
        from bev_mdo import interrupts

        interrupts.new_run()  # not what an earlier run noted of its bag
        try:
            return method(*args, **kwargs)
        except KeyboardInterrupt as exc:
            for line in interrupts.interrupted_lines(exc):
                exc.add_note(line)
            raise
    return call


def _mapping(value, what: str) -> dict:
    """A {name: value} argument as a dict; InputError for anything else (a list of values, a number)."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise InputError(f"{what} must be a mapping of names to values, got {type(value).__name__}")
    return dict(value)


def _number(value, what: str) -> float:
    """A finite number (not a bool, a string or a list); InputError naming ``what`` otherwise."""
    if not real_number(value) or not math.isfinite(value):
        raise InputError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _whole(value, what: str) -> int:
    """A count (starts, samples, generations, pop, order) as a whole number (models.common.check_whole: 2.9
    ran 2 starts, "3" ran 3, True ran 1), or with ``what`` "seed" a seed as ``--seed`` takes it (check_seed);
    InputError naming ``what`` otherwise."""
    from bev_mdo.models.common import check_seed, check_whole

    try:
        return (check_seed if what == "seed" else check_whole)(value)
    except ValueError as exc:
        raise InputError(f"{what} {exc}") from None


def _transport(value) -> Transport:
    """A run's ``transport=``: a name or a ``Transport``. Anything else (a dict, None, 5) was read for the
    attributes it lacks and ran over ROS, the default; InputError naming it now."""
    if isinstance(value, (str, Transport)):
        return Transport.of(value)  # a Transport's own fields (an OptimizeOptions given holds more)
    raise InputError(f"transport must be a name ({' or '.join(map(repr, TRANSPORTS))}) or a Transport, got {value!r}")


def _name(value, what: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"{what} must be a name, got {value!r}")
    return value


def _names(value, what: str) -> list[str] | None:
    """A list of names (one name, or "a,b" as the CLI writes it, is taken too); InputError otherwise."""
    if value is None:
        return None
    if isinstance(value, str):
        return [v.strip() for v in value.split(",") if v.strip()]
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{what} must be a list of names, got {value!r}")
    return list(value)


class Study:
    """A run config and the changes made to its problem.

    ``Study("config/leaf_nedc.yaml")`` or ``Study({...})`` (the same keys as the YAML file, copied as they
    are then); the config is checked at once. ``bound``, ``initial``, ``constrain`` and ``objective`` change the
    problem (like ``--bound``, ``--initial``, ``--constraint``, ``--objective``/``--maximize``) and
    return the study, so they chain. ``config`` is the effective, checked config a run records.
    Runs take ``transport="ros"`` (the default of every run and every ``bev-mdo`` command: the config's
    discipline nodes started for the run and stopped after), ``"inprocess"`` (no ROS) or a ``Transport``
    (``attach`` to the nodes already running, ``domain_id``, ``discovery``...).
    """

    @_input_errors
    def __init__(self, config: str | Path | Mapping[str, Any]):
        from bev_mdo.config import RunConfig

        if not isinstance(config, (str, Path, Mapping)):
            raise InputError(f"a study's config is a YAML file or a mapping, got {type(config).__name__}")
        self.source = str(config) if isinstance(config, (str, Path)) else "<config>"
        # the mapping as it is now: a later edit of the caller's dict (or of a nested part) is not this study's
        self._raw = config if isinstance(config, (str, Path)) else copy.deepcopy(dict(config))
        self.overrides = Overrides()
        self._config = RunConfig.load(self._raw)  # the config as written must be valid

    @property
    def config(self):
        """The effective config (``RunConfig``: typed parts; as a mapping, the resolved dict): a copy, so that an
        edit of it (which a run would not see) changes nothing; bound(), constrain(), ... change the study."""
        return copy.deepcopy(self._config)

    def _change(self, edit) -> "Study":
        from bev_mdo.api import overrides

        new = copy.deepcopy(self.overrides)
        edit(new)
        self._config = _input_errors(overrides.load)(self._raw, new)  # checked now, not at the run
        self.overrides = new
        return self

    @_input_errors
    def bound(self, name: str, lower: float | None = None, upper: float | None = None) -> "Study":
        """New bounds of a design variable (a side left None keeps its value)."""
        new = {k: _number(v, f"bound {_name(name, 'bound: the design variable')!r}: {k}")
               for k, v in (("lower", lower), ("upper", upper)) if v is not None}

        def edit(ov):
            lo, hi = ov.bounds.get(name, (None, None))
            ov.bounds[name] = (new.get("lower", lo), new.get("upper", hi))
        return self._change(edit)

    @_input_errors
    def initial(self, name: str, value: float) -> "Study":
        """The initial value of a design variable."""
        x = _number(value, f"initial {_name(name, 'initial: the design variable')!r}")
        return self._change(lambda ov: ov.initial.__setitem__(name, x))

    @_input_errors
    def constrain(self, name: str, lower: float | None = None, upper: float | None = None) -> "Study":
        """Add or change a constraint on an output: ``lower <= name <= upper``."""
        if lower is None and upper is None:
            raise InputError(f"constrain {name!r}: give lower or upper")
        limits = {k: _number(v, f"constrain {_name(name, 'constrain: the output')!r}: {k}")
                  for k, v in (("lower", lower), ("upper", upper)) if v is not None}
        return self._change(lambda ov: ov.constraints.setdefault(name, {}).update(limits))

    @_input_errors
    def objective(self, name: str | None = None, maximize: bool | None = None) -> "Study":
        """The output to optimise and whether it is maximised (None keeps the config's)."""
        if name is not None:
            _name(name, "objective: the output")
        if maximize is not None and maximize not in (True, False):  # a numpy bool too; 'no' is not False
            raise InputError(f"objective: maximize must be True or False, got {maximize!r}")

        def edit(ov):
            ov.objective = name if name is not None else ov.objective
            ov.maximize = bool(maximize) if maximize is not None else ov.maximize
        return self._change(edit)

    @_input_errors
    def evaluate(self, design: Mapping[str, float] | None = None, transport=DEFAULT_TRANSPORT) -> EvaluateResult:
        """One design through every discipline; variables not given take their initial value."""
        from bev_mdo.api import evaluate

        return EvaluateResult.of(evaluate.design(self._config, _mapping(design, "design"), _transport(transport),
                                                 caller="bev_mdo Study.evaluate"))

    @_input_errors
    @_bag_notes
    def optimize(self, formulation: str | None = None, optimizer: str | None = None, *, starts: int = 1,
                 seed: int = 0, x0: Mapping[str, float] | None = None, bag: str | None = None, callback=None,
                 transport=DEFAULT_TRANSPORT, **ros) -> OptimizeResult:
        """Optimise the problem (``bev-mdo optimize``). ``starts`` > 1: from a Latin hypercube of start points
        drawn with ``seed``, which also seeds differential_evolution when its options give no seed;
        ``callback(record)`` sees every iteration; ``bag`` writes the run's bag there; ``ros``: OptimizeOptions'
        ROS settings (instances: N, {name: N} or "name=N,...", compose, no_record) and fixed_budget."""
        from bev_mdo.api import optimize
        from bev_mdo.api.overrides import finite_values
        from bev_mdo.models.common import check_keys

        own = {"formulation", "optimizer", "starts", "seed", "x0", "bag", "callback", "transport"}
        check_keys("", ros, own | {f.name for f in fields(optimize.OptimizeOptions)} - {f.name for f in fields(Transport)}
                   - {"quiet", "bag_flag", "progress_to_stderr"}, of="optimize()")
        opts = optimize.OptimizeOptions(**asdict(_transport(transport)), formulation=formulation, optimizer=optimizer,
                                        starts=_whole(starts, "starts"), seed=_whole(seed, "seed"), bag=bag, quiet=True, **ros)
        x0 = _mapping(x0, "x0")
        finite_values(x0, "x0", one="the start point, a number per name")
        if callback is not None and not callable(callback):
            raise InputError(f"callback must be a function of one iteration record, got {callback!r}")
        return OptimizeResult.of(optimize.run(self._config, opts, callback, x0 or None))

    @_input_errors
    def sweep(self, doe: str | None = None, samples: int = 64, seed: int = 1, *,
              designs: Mapping[str, Any] | None = None, fixed: Mapping[str, float] | None = None,
              transport=DEFAULT_TRANSPORT) -> SweepResult:
        """A batch of designs: a DOE over the bounds (``doe`` lhs (the default), sobol, halton or full; ``samples``
        designs, full: levels per variable), or the given ``designs`` {name: values} (not both); ``fixed``
        values for variables not varied (others keep their initial value)."""
        import numpy as np

        from bev_mdo.api import doe as sampling, evaluate
        from bev_mdo.api.overrides import finite_values

        how = _transport(transport)
        fixed = _mapping(fixed, "fixed")
        finite_values(fixed, "fixed", one="a variable held at one value (vary it in designs=)")
        fixed = {k: float(v) for k, v in fixed.items()}
        cols = None
        if designs is not None and doe is not None:  # a DOE asked for beside given designs was ignored
            raise InputError(f"sweep: doe={doe!r} and designs= given: a DOE draws its designs, designs= are evaluated "
                             "as given; give one")
        if designs is not None:
            finite_values(_mapping(designs, "designs"), "designs")  # None named as None, not as nan
            cols = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in _mapping(designs, "designs").items()}
            if len({c.shape for c in cols.values()}) > 1 or any(c.ndim != 1 for c in cols.values()):
                raise InputError("designs: give every variable's values as one list, all of the same length "
                                 f"(got {', '.join(f'{k}: {c.shape[0] if c.ndim == 1 else c.shape}' for k, c in cols.items())})")
        cols = sampling.batch(self._config.problem, doe or "lhs", _whole(samples, "samples"), _whole(seed, "seed"), cols,
                              fixed)
        r = evaluate.batch(self._config, cols, how)
        return SweepResult(r["design"], r["outputs"], r["margins"], r["feasible"], r["ok"], list(r["errors"]),
                           r["objective"], bool(getattr(r["problem"], "maximize", False)))

    @_input_errors
    def sensitivity(self, at: Mapping[str, float] | None = None, wrt: list[str] | None = None, order: int = 2,
                    rel_step: float | None = None, transport=DEFAULT_TRANSPORT) -> SensitivityResult:
        """Normalised first- (and second-) order sensitivities at ``at`` (default: the initial design)
        with respect to ``wrt`` (design variables and model parameters; default: the design variables)."""
        from bev_mdo.api import sensitivity

        s, outputs, _, _ = sensitivity.run(self._config, _mapping(at, "at"), _names(wrt, "wrt"), _transport(transport),
                                           order=_whole(order, "order"),
                                           rel_step=None if rel_step is None else _number(rel_step, "rel_step"))
        units = sensitivity.units_of(self._config, [*s.names, *outputs])
        return SensitivityResult.of(sensitivity.to_dict(s, outputs, units))

    @_input_errors
    def global_sensitivity(self, method: str = "sobol", samples: int | None = None, seed: int = 1,
                           conf_level: float = 0.95, at: Mapping[str, float] | None = None,
                           wrt: list[str] | None = None, transport=DEFAULT_TRANSPORT) -> GlobalSensitivityResult:
        """Sobol' (first-order and total) or Morris indices over the bounds of ``wrt`` (default: every
        design variable); the others keep their value at ``at``. ``samples``: sobol's base N (a power
        of 2, default 1024: N (D + 2) designs), morris' trajectories (default 64)."""
        from bev_mdo.api import sensitivity

        rep = sensitivity.run(self._config, _mapping(at, "at"), _names(wrt, "wrt"), _transport(transport),
                              global_method=method, samples=None if samples is None else _whole(samples, "samples"),
                              seed=_whole(seed, "seed"), conf_level=conf_level)
        return GlobalSensitivityResult.of(rep)

    @_input_errors
    @_bag_notes
    def pareto(self, objectives: list[str] | None = None, generations: int = 30, pop: int = 100, seed: int = 1,
               out: str | None = None, plots: bool = False, transport=DEFAULT_TRANSPORT,
               instances: str | int | Mapping[str, int] | None = None) -> ParetoResult:
        """The NSGA-II Pareto front of ``objectives`` (minimised; default: the config's
        ``problem.objectives``), written with its bag into ``out`` (default bags/<name>_pareto_<time>)."""
        from bev_mdo.api import pareto

        doc, _ = pareto.run(self._config, _names(objectives, "objectives"),
                            generations=_whole(generations, "generations"), pop=_whole(pop, "pop"), seed=_whole(seed, "seed"),
                            out=out, transport=_transport(transport), instances=instances, plots=plots,
                            source=self.source)
        return ParetoResult.of(doc)
