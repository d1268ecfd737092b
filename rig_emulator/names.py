"""Names people read (boilers, register points and devices, TLS roles): which characters
no name may hold, and how a message shows them. Pure text: every layer may use it.

A control character writes lines of its own into a log or a terminal; a format character
(soft hyphen, zero-width space, a bidi override such as U+202E) makes a name display as
another, but for the zero-width non-joiner and joiner, which are part of the spelling of
names (Persian, the Indic scripts, emoji sequences such as a scientist's; refusing them
refused role names that worked before: a re-probe); spaces of any kind (Zs) are text.
"""

from __future__ import annotations

import unicodedata

#: The Unicode categories (``unicodedata.category``) no name holds and a message shows
#: escaped, with why
HIDDEN_CATEGORIES = {
    "Cc": "a control character",
    "Cf": "a format character, which makes a name display as another",
    "Zl": "a line separator",
    "Zp": "a paragraph separator",
    "Cs": "a surrogate",
    "Co": "a private-use character",
    "Cn": "an unassigned code point",
}
#: The format characters that are part of the spelling of names: the zero-width non-joiner
#: and joiner
SPELLING_FORMAT_CHARACTERS = frozenset("\u200c\u200d")


def _hidden(character: str) -> bool:
    return (
        unicodedata.category(character) in HIDDEN_CATEGORIES
        and character not in SPELLING_FORMAT_CHARACTERS
    )


def shown(text: str) -> str:
    """``text`` as a message or log shows it: as written, but each character of
    :data:`HIDDEN_CATEGORIES` escaped as Python writes it (``\\n``, ``\\u202e``), the same
    everywhere (a role ``Ingenieur \u00c4`` read so in the start-up summary but ``Ingenieur
    \\xc4`` in the connection lines: a stranger's probe)."""
    return "".join(c.encode("unicode_escape").decode("ascii") if _hidden(c) else c for c in text)


def hidden_character(text: str) -> str | None:
    """Why ``text`` may not be a name (its first character of :data:`HIDDEN_CATEGORIES`,
    by code point, name and category: ``U+202E RIGHT-TO-LEFT OVERRIDE: a format
    character, ...``), or None if it holds none."""
    hidden = next((c for c in text if _hidden(c)), None)
    if hidden is None:
        return None
    called = unicodedata.name(hidden, "")
    return (
        f"U+{ord(hidden):04X}{' ' + called if called else ''}: "
        f"{HIDDEN_CATEGORIES[unicodedata.category(hidden)]}"
    )
