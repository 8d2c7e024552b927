"""Command line: one module per subcommand, each exposing ``register(subparsers)``.

A module registers its parser and sets ``func`` (``args -> exit code``) as a default.  Registering
is cheap (every command builds every parser): options that need heavy imports (methods tables,
the renderer's checks) go in a ``fill`` function passed to ``add_parser``, run when that parser
is used (:class:`pbrbench.cli.main.Parser`), so ``pbrbench --help`` and usage errors answer at once.
Exit codes: 0 ok, 1 user error, 2 regressions found.
"""
