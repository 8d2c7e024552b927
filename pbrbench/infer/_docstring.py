"""Shared docstring fragments, substituted into the methods' numpydoc docstrings.

The methods of one problem share most of their Parameters, Returns and Raises text (the
problem's signature).  That text is written once, in the problem's ``_common`` module, as a
dict of fragments, and each method's docstring names the fragment it uses on a line of its own,

.. code-block:: text

    Parameters
    ----------
    %(images_lights)s
    max_iter : int
        Iterations (>= 1).

which :func:`docstring` replaces by the fragment, indented like the placeholder line, when the
module is imported (as scikit-image's and matplotlib's ``_docstring`` helpers do), so that
``help()`` and the rendered documentation show the whole text.  Only whole-line placeholders
are replaced: the ``%`` and braces of the equations are left alone.
"""

from __future__ import annotations

import re
import textwrap

__all__ = ["docstring", "methods_list", "substitute"]

_PLACEHOLDER = re.compile(r"^(?P<indent>[ \t]*)%\((?P<key>\w+)\)s[ \t]*$", re.MULTILINE)


def substitute(doc: str, fragments: dict[str, str]) -> str:
    """``doc`` with every line ``%(key)s`` replaced by ``fragments[key]`` at that line's indent.

    Raises ``KeyError`` naming a placeholder that has no fragment (a typo must not leave the
    placeholder in ``help()``).
    """

    def repl(m: re.Match) -> str:
        key = m.group("key")
        if key not in fragments:
            raise KeyError(f"docstring placeholder %({key})s has no fragment; known: {sorted(fragments)}")
        return textwrap.indent(textwrap.dedent(fragments[key]).strip("\n"), m.group("indent"))

    return _PLACEHOLDER.sub(repl, doc)


def docstring(fragments: dict[str, str]):
    """Decorator: substitute ``fragments`` into the function's docstring (the function itself is
    returned, not wrapped)."""

    def deco(fn):
        if fn.__doc__:
            fn.__doc__ = substitute(fn.__doc__, fragments)
        return fn

    return deco


def methods_list(table: dict) -> str:
    """A numpydoc-friendly bullet list of a methods table: ``name``, the function, and the first
    line of its docstring (generated from the table, so it never lags behind it)."""
    lines = []
    for name, fn in table.items():
        summary = fn.__doc__.strip().splitlines()[0] if fn.__doc__ else ""
        lines.append(f'- ``"{name}"``: :func:`{fn.__name__}`: {summary}')
    return "\n".join(lines)
