"""A run config, parsed and validated once (``RunConfig.load``): the typed object every command,
session and node takes. ``load``: the loading and the top-level checks; ``sections``: each
section's checks; ``disciplines``: the run's disciplines built, checked against the problem and
listed for the nodes."""
from bev_mdo.config.disciplines import discipline_entries, discipline_names, resolve_disciplines
from bev_mdo.config.load import (MDA_DEFAULTS, OPTIMIZER_DEFAULTS, RunConfig, check_run_name, load_config, plain,
                                 read_config_file, run_settings)
from bev_mdo.config.sections import check_optimizer_options

__all__ = ["MDA_DEFAULTS", "OPTIMIZER_DEFAULTS", "RunConfig", "check_optimizer_options", "check_run_name",
           "discipline_entries", "discipline_names", "load_config", "plain", "read_config_file", "resolve_disciplines", "run_settings"]
