"""Errors about user input. The command line prints them as one line and exits with 2."""


class InputError(ValueError):
    """A problem with an input file or value, worded for the user (name the file and key)."""
