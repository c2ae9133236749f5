"""Typed settings of a run's engine sections (``mda:``, ``optimizer:``), defaults defined once.

``config.py`` validates the sections of a config against these (its ``MDA_DEFAULTS`` and
``OPTIMIZER_DEFAULTS`` are these defaults) and fills every key in; the driver reads a resolved
config's sections through ``MDASettings.of`` / ``OptimizerSettings.of``, which take the section as
it is: no default is applied a second time, and a section that is not resolved (a key missing,
one too many) raises instead of being guessed at.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
from typing import Any

# Largest violation of a normalised constraint (and of an IDF consistency equality) that counts as
# feasible. Constraints are normalised by their scale (default max(|bound|, 1)), so this is relative
# to the bound for bounds of magnitude >= 1 and absolute below. 1e-4 is GEMSEO's default
# (ineq_tolerance / eq_tolerance).
FEASIBILITY_TOL = 1e-4


def _of(cls, section: Mapping[str, Any] | None, where: str):
    if not isinstance(section, Mapping):
        raise ValueError(f"{where}: a resolved section is a mapping (load the config with config.load_config)")
    names = [f.name for f in fields(cls)]
    missing = [k for k in names if k not in section]
    unknown = sorted(set(section) - set(names))
    if missing or unknown:
        raise ValueError(f"{where}: not a resolved section (missing {missing}, unknown {unknown}); "
                         "load the config with config.load_config")
    return cls(**{k: section[k] for k in names})


@dataclass(frozen=True)
class MDASettings:
    """The ``mda:`` section (mda.py's MDA takes these as keywords)."""

    method: str = "gauss_seidel"
    tolerance: float = 1.0e-10
    max_iterations: int = 100
    relaxation: float = 1.0
    warm_start: bool | str = "auto"   # mda.py: auto = on for newton only
    fuse_downstream: bool = False

    @classmethod
    def of(cls, section: Mapping[str, Any] | None) -> "MDASettings":
        return _of(cls, section, "mda")

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class OptimizerSettings:
    """The ``optimizer:`` section."""

    name: str = "SLSQP"
    options: Mapping[str, Any] = field(default_factory=dict)
    fd_step: float = 1.0e-6
    fd_scheme: str = "forward"
    feasibility_tolerance: float = FEASIBILITY_TOL
    derivatives: str = "auto"

    @classmethod
    def of(cls, section: Mapping[str, Any] | None) -> "OptimizerSettings":
        return _of(cls, section, "optimizer")

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class RunSettings:
    """What the engine needs of a run, typed and validated once: ``config.run_settings`` builds it
    from a resolved config (the engine imports nothing above it) and the driver reads only this.

    ``disciplines``: the run's disciplines by name (the evaluator may serve more); ``partials``:
    whether each provides analytic partials (``optimizer.derivatives: auto`` needs it over a
    transport that does not say, e.g. ROS)."""

    problem: Mapping[str, Any]
    formulation: str
    mda: MDASettings
    optimizer: OptimizerSettings
    disciplines: tuple[str, ...]
    partials: Mapping[str, bool]
    parsed_problem: Any = field(default=None, compare=False, repr=False)  # the Problem of ``problem``, if built
    # the disciplines' judgement of an analysed design beyond its constraints (config: a motor that cannot follow
    # the cycle): ``design_check({variable: value})`` -> one line per reason the design is infeasible, [] for none.
    # Every feasibility the engine states (iteration records, the result, its verdict, multi-start) applies it.
    design_check: Callable[[Mapping[str, float]], list[str]] | None = field(default=None, compare=False, repr=False)
    # the same of a batch ({variable: (N,) values}) -> (N,) bool, True where it rules the design out (pareto)
    designs_check: Callable[[Mapping[str, Any]], Any] | None = field(default=None, compare=False, repr=False)

    def optimisation_problem(self):
        """The ``Problem`` of ``problem``: the one the config built at load, else built here."""
        from bev_mdo.mdo.problem import Problem

        return self.parsed_problem if self.parsed_problem is not None else Problem.from_config(self.problem)

    @classmethod
    def of(cls, run: "RunSettings | Mapping[str, Any]", evaluator: Any = None) -> "RunSettings":
        """``run`` itself, or one from a resolved config and an evaluator that declares every
        discipline's partials (the in-process one, built from ``config.resolve_disciplines``: it
        serves exactly the run's disciplines, in their order). Over a transport that does not
        declare them (ROS), pass ``config.run_settings(config)``: ValueError here."""
        if isinstance(run, RunSettings):
            return run
        specs = dict(getattr(evaluator, "specs", None) or {})
        entries = run.get("disciplines")
        names = (tuple(e if isinstance(e, str) else e["name"] for e in entries) if entries is not None
                 else tuple(specs))
        partials = {n: getattr(specs.get(n), "partials", None) for n in names}
        if evaluator is not None and any(p is None for p in partials.values()):
            raise ValueError("this evaluator does not declare its disciplines' partials: pass the run's "
                             "settings, config.run_settings(config), instead of the config")
        return cls(run["problem"], str(run["formulation"]), MDASettings.of(run["mda"]),
                   OptimizerSettings.of(run["optimizer"]), names, {n: bool(p) for n, p in partials.items()})
