"""The one exception of bad user input: the API raises it, the CLI prints its message and exits 2."""


class InputError(ValueError):
    """A mistake in the input (config, name, value, file): one line that names it, e.g.
    ``--bound 'motr_kw': not a design variable; did you mean 'motor_kw'?``."""


class ModelFailed(RuntimeError):
    """The model gave no value at points a method needs all of (a global sensitivity's sample): one line naming
    how many and the first, its design; the CLI exits 1, as for a result point that failed."""
