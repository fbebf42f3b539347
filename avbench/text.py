"""Plain text from reST: docstrings (with ``literals``, :func:`roles` and directives) shown as help.

A leaf module: the command line (:mod:`avbench.cli`) and the benchmarks' own command
(:mod:`avbench.bench.__main__`) both print docstrings as help.
"""

import re

__all__ = ["plain_text"]

_REST = [
    (re.compile(r":[a-z]+:`~?([^`<]*?)(?:\s*<[^>]*>)?`"), r"\1"),  # :func:`x`, :class:`~a.b`, :ref:`t <x>`
    (re.compile(r"``([^`]*)``"), r"\1"),  # ``literal``
    (re.compile(r"`([^`]*)`_?"), r"\1"),  # `text`, `link`_
    (re.compile(r"^\.\. [a-z-]+::.*$", re.MULTILINE), ""),  # directives
]


def plain_text(text: str) -> str:
    """``text`` without reST markup (double back-quotes, roles, directives): help shows plain text."""
    for pattern, repl in _REST:
        text = pattern.sub(repl, text)
    return text
