"""The error of a command line that must not start."""


class CommandLineError(ValueError):
    """A command line that must not start: the message is one line."""
