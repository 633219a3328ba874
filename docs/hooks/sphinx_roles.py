"""MkDocs hook: the docstrings cross-reference with Sphinx roles (``:func:`fit```), which
mkdocstrings shows as written; the rendered pages keep the code name and drop the role."""

from __future__ import annotations

import re

ROLE = re.compile(r":(?:py:)?(?:func|meth|class|data|attr|mod|exc|obj|const):(<code>)~?")


def on_page_content(html: str, page, config, files) -> str:
    return ROLE.sub(r"\1", html)
