"""Errors the user can act on: the CLI prints them as one line, without a traceback."""


class InputError(ValueError):
    """Bad user input: the message names the file or value and what is wrong with it."""
