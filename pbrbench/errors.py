"""Errors meant for users: the CLI prints them as one line and exits with code 1."""


class UserError(Exception):
    """A problem with the user's input (a scene file, an argument, the environment).

    The message is one line: what is wrong, where (file, key path, argument) and how to fix it.
    """


class SceneError(UserError):
    """A scene file that cannot be parsed or does not validate."""
