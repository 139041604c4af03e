"""Griffe extension for the API reference: Sphinx cross-reference roles in docstrings shown as code.

The engine's numpydoc docstrings name other objects with Sphinx roles (``:func:`fit_trend```,
``:mod:`~engine.history.trend```). mkdocstrings does not read them and would print the role as
text; this rewrites each to inline code (the ``~`` form keeps the last name only, as Sphinx shows
it) before the docstring is parsed. Loaded by ``mkdocs.yml`` (``extensions``); not part of the
product.
"""

from __future__ import annotations

import re
from typing import Any

from griffe import Extension, Object

ROLE = re.compile(r":(?:py:)?(?:func|meth|class|mod|data|attr|exc|obj|const|ref):`(~?)([^`]+)`")


def plain(text: str) -> str:
    """``:role:`~a.b.c``` -> ```c```, ``:role:`a.b``` -> ```a.b```."""

    def one(m: re.Match[str]) -> str:
        target = m.group(2).strip()
        if m.group(1):
            target = target.rsplit(".", 1)[-1]
        return f"`{target}`"

    return ROLE.sub(one, text)


class SphinxRoles(Extension):
    """Rewrite the roles of every object's docstring."""

    def on_instance(self, *, obj: Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain(obj.docstring.value)
