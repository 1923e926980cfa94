"""User-facing errors: raised for bad input, printed by the CLI as one line with exit code 2."""


class UsageError(ValueError):
    """A bad user-supplied value; the message names the value and what is allowed."""
