"""Names people read (boilers, register points and devices, TLS roles): which characters
no name may hold, and how a message shows them. Pure text: every layer may use it.

A control character writes lines of its own into a log or a terminal; a format character
(soft hyphen, zero-width space, a bidi override such as U+202E) makes a name display as
another, but for those that are part of the spelling of names
(:data:`SPELLING_FORMAT_CHARACTERS`: Persian, the Indic scripts, mixed-direction names,
emoji sequences such as a scientist's; refusing them refused names that worked before:
re-probes); spaces of any kind (Zs) are text.
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
#: and joiner, the left-to-right, right-to-left and Arabic letter marks (a Hebrew or Arabic
#: name with a Latin "6kW" needs them to display in order), and the tag characters of emoji
#: flag sequences (U+E0020..U+E007F); boiler names with them were refused (a re-probe).
#: The embeddings, overrides and isolates (U+202A..U+202E, U+2066..U+2069) stay refused:
#: they reorder what follows them, a name displaying as another.
SPELLING_FORMAT_CHARACTERS = frozenset("\u200c\u200d\u200e\u200f\u061c")
EMOJI_TAGS = range(0xE0020, 0xE0080)


def _hidden(character: str) -> bool:
    return (
        unicodedata.category(character) in HIDDEN_CATEGORIES
        and character not in SPELLING_FORMAT_CHARACTERS
        and ord(character) not in EMOJI_TAGS
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


#: The longest host name the resolver takes, in characters without the root's dot (RFC
#: 1035's 255 octets on the wire).
HOST_NAME_MAX = 253


def host_name_problem(host: str) -> str | None:
    """What makes ``host`` no host name the resolver can be asked for, or None (a probe:
    ``lab..local`` ended in a traceback from Python's idna codec; a 319-character name,
    and one of 245 characters but 281 in IDNA, went to the resolver)."""
    try:
        encoded = host.encode("idna")  # what the resolver gets: 'ü' is 'xn--tda'
    except UnicodeError as exc:
        why = str(exc.__cause__ or exc).removeprefix("UnicodeError: ")
        if "too long" in why:  # ("label empty or too long", "label too long")
            return "a label between dots is empty or over 63 characters"
        # (a mixed-direction label, a lone surrogate: told as empty or too long, a re-probe)
        return f"not a name IDNA can encode: {why}"
    if len(encoded.rstrip(b".")) > HOST_NAME_MAX:
        idna = " in IDNA" if len(encoded) != len(host) else ""
        return f"{len(encoded)} characters{idna}, over {HOST_NAME_MAX}"
    return None
