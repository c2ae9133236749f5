"""The one exception of bad user input: the API raises it, the CLI prints its message and exits 2."""


class InputError(ValueError):
    """A mistake in the input (config, name, value, file): one line that names it, e.g.
    ``--bound 'motr_kw': not a design variable; did you mean 'motor_kw'?``."""
