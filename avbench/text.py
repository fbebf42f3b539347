"""Plain text from reST: docstrings (with ``literals``, :func:`roles` and directives) shown as help.

A leaf module: the command line (:mod:`avbench.cli`) and the benchmarks' own command
(:mod:`avbench.bench.__main__`) both print docstrings as help.
"""

import re

__all__ = ["empty_is_none", "plain_text"]

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


def empty_is_none(value: str) -> str:
    """The argparse type of an option whose empty (or blank) value asks for none of the thing
    (``--title ''``: no title), where every other option refuses an empty value
    (:func:`avbench.cli._empty_values`).

    >>> empty_is_none("  "), empty_is_none("run 3")
    ('', 'run 3')
    """
    return value if value.strip() else ""
