"""Errors the user can act on: the CLI prints them as one line, without a traceback."""


class InputError(ValueError):
    """Bad user input: the message names the file or value and what is wrong with it."""


class PairGeometryError(InputError):
    """An image pair that cannot be rectified usefully (no common footprint, too oblique, no
    baseline): the pipeline skips such a pair; called directly, it is the caller's input."""
