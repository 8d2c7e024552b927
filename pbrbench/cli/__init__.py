"""Command line: one module per subcommand, each exposing ``register(subparsers)``.

A module registers its parser and sets ``func`` (``args -> exit code``) as a default.
Exit codes: 0 ok, 1 user error, 2 regressions found.
"""
