"""The one error a run file is refused with, and the one way a file's text enters it.

A run file may come from anyone: a field may hold megabytes, a member's name control
characters. Every message that shows something of the file goes through :func:`quote` (a value
as ``repr`` shows it) or :func:`clip` (text as plain words), which show at most
:data:`QUOTE_CHARS` characters of it, escaped, so an error is one short line whatever
the file holds.
"""

from __future__ import annotations

import reprlib

#: The most characters of a file's text a message shows.
QUOTE_CHARS = 200


class RunFileError(ValueError):
    """A run file (or a run to write) refused: the message says what is wrong and what to do."""


def clip(text: str, limit: int = QUOTE_CHARS) -> str:
    """``text`` as plain words in a message: at most ``limit`` characters, anything not
    printable (a newline, a NUL) escaped, "…" where it was cut.

    >>> clip("a\\nb" + "c" * 300, 6)
    'a\\\\nbccc…'
    """
    cut = text[:limit]
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in cut)
    return shown + ("…" if len(text) > limit else "")


def quote(value: object, limit: int = QUOTE_CHARS) -> str:
    """``value`` as a message shows it: ``repr`` of at most ``limit`` characters of its text
    (a string as it is, anything else as ``repr``), its length told when cut.

    >>> quote("abc")
    "'abc'"
    >>> quote("x" * 1000, 5)
    "'xxxxx'… (1000 characters)"
    """
    if isinstance(value, str):
        text = value
        if len(text) <= limit:
            return repr(text)
        return f"{text[:limit]!r}… ({len(text)} characters)"
    if isinstance(value, bytes | bytearray):
        if len(value) <= limit:
            return repr(bytes(value))
        return f"{bytes(value[:limit])!r}… ({len(value)} bytes)"
    try:
        text = _REPR.repr(value)
    except Exception:  # noqa: BLE001 - a value that cannot even be shown (an int too long)
        return f"<{type(value).__name__}>"
    if len(text) <= limit:
        return text
    return f"{text[:limit]}… ({type(value).__name__}, cut)"


def _bounded_repr() -> reprlib.Repr:
    """A ``repr`` that never builds a huge text: long strings, deep or long containers
    and big integers are cut as it goes."""
    r = reprlib.Repr()
    r.maxlevel, r.maxdict, r.maxlist, r.maxtuple, r.maxset = 3, 8, 8, 8, 8
    r.maxstring, r.maxother, r.maxlong = 60, 60, 40
    return r


_REPR = _bounded_repr()
