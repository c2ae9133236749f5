"""The run's configuration as a bag stores it, parsed once per opened bag (``Bag.stored_config``)."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

WINDOW_S = 30.0  # as ros.sign_window_s: a record received further than this from its stamp is expired


@dataclass(frozen=True)
class StoredConfig:
    """``text``: the stored YAML ('' without one); ``data``: it parsed ({} unless it is a readable mapping: a
    reader never fails on the stored config), which ``window_s``, ``is_design`` and ``maximized`` read."""

    text: str
    data: dict

    @classmethod
    def parse(cls, text: str | None) -> StoredConfig:
        """Within the limits of a user's YAML (yamlload): a bag may come from anyone, and its config's alias
        bomb (a few lines, billions of values once expanded) was parsed whole for every reader."""
        from bev_mdo.yamlload import load_yaml

        try:
            data = load_yaml(text or "")
        except Exception:  # noqa: BLE001 - a reader never fails on the stored config
            data = None
        return cls(text or "", data if isinstance(data, dict) else {})

    @property
    def window_s(self) -> float:
        """The run's ``ros.sign_window_s`` (``WINDOW_S`` without a valid one)."""
        try:
            value = float((self.data.get("ros") or {}).get("sign_window_s", WINDOW_S))
        except Exception:  # noqa: BLE001 - a reader never fails on the stored config
            return WINDOW_S
        return value if value > 0 else WINDOW_S

    @cached_property
    def _design_variables(self) -> dict | None:
        from bev_mdo.config.sections import resolve_problem

        try:  # as the run read it: a battery sized for range is a coupling
            dvs = resolve_problem(self.data.get("problem")).get("design_variables")
        except Exception:  # noqa: BLE001 - a reader never fails on the stored config
            return None
        return dvs if isinstance(dvs, dict) and dvs else None

    def is_design(self, name: str) -> bool:
        """Whether a recorded variable name is a design variable of the stored problem (``x[2]``: of ``x``);
        an IDF record holds its couplings too. Without a readable config, every name is."""
        dvs = self._design_variables
        return dvs is None or name in dvs or name.split("[", 1)[0] in dvs

    @property
    def maximized(self) -> bool:
        """Whether the stored problem maximises its objective (problem.objective: {maximize: true})."""
        problem = self.data.get("problem")
        obj = problem.get("objective") if isinstance(problem, dict) else None
        return isinstance(obj, dict) and obj.get("maximize") is True
