"""Validation errors in the scene's words.

The scene schema is checked by a validation library whose messages speak of inputs,
fields and types ("Field required", "Input should be a valid dictionary").  Every error
it reports is a dict (``type``, ``loc``, ``msg``, ``input``, ``ctx``);
:func:`validation_line` turns one into one line that names the scene key, says what the
key accepts and the value received: ``simulation.region: must hold 4 values [x0, y0,
x1, y1]; received [0, 0, 1]``.  Every error type the library defines has a wording here
(a test goes through them all); an unknown one is rewritten by its message's grammar.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["validation_line", "shown", "bound_text", "NUMERIC_ERRORS", "LIBRARY_WORDING"]

#: error types about a number (the allowed range comes from the schema when it is known)
NUMERIC_ERRORS = frozenset({
    "float_type", "float_parsing", "int_type", "int_parsing", "int_parsing_size",
    "int_from_float", "finite_number", "greater_than", "greater_than_equal", "less_than",
    "less_than_equal", "multiple_of", "decimal_type", "decimal_parsing", "decimal_max_digits",
    "decimal_max_places", "decimal_whole_digits", "complex_type", "complex_str_parsing",
    "fraction_type", "fraction_parsing"})
#: phrases of the validation library that must not reach a user
LIBRARY_WORDING = ("Input should", "Field required", "Value error", "valid dictionary",
                   "instance of", "[type=", "pydantic", "after validation", "Extra inputs",
                   "Unable to extract tag", "found using", "Assertion failed", "Input tag")

_TABLE = "must be a table of keys (a [section], or {key = value, ...} on one line)"
_ARRAY = "must be an array [a, b, ...]"
_WORDS = {
    "missing": "is required here (it has no default): add it",
    "extra_forbidden": "unknown key (not allowed here; check the spelling)",
    "bool_type": "must be true or false",
    "bool_parsing": "must be true or false",
    "string_type": "must be text (in quotes)",
    "string_unicode": "must be text (valid Unicode)",
    "string_not_ascii": "must be ASCII text",
    "none_required": "must be left out here",
    "dict_type": _TABLE, "model_type": _TABLE, "model_attributes_type": _TABLE,
    "mapping_type": _TABLE, "dataclass_type": _TABLE, "dataclass_exact_type": _TABLE,
    "frozen_dict_type": _TABLE, "ordered_dict_type": _TABLE, "counter_type": _TABLE,
    "invalid_key": "must have text keys",
    "list_type": _ARRAY, "tuple_type": _ARRAY, "set_type": _ARRAY, "frozen_set_type": _ARRAY,
    "deque_type": _ARRAY, "iterable_type": _ARRAY, "named_tuple_type": _ARRAY,
    "iteration_error": "must be an array whose items can be read",
    "set_item_not_hashable": "must hold plain values (no tables or arrays) in this array",
    "recursion_loop": "nests tables or arrays too deeply",
    "recursion_depth_exceeded": "nests tables or arrays too deeply",
    "json_invalid": "must be valid JSON", "json_type": "must be JSON text",
    "frozen_field": "cannot be changed", "frozen_instance": "cannot be changed",
    "bytes_type": "must be text", "bytes_invalid_encoding": "must be text in a valid encoding",
    "callable_type": "must be a value, not code", "is_instance_of": "has the wrong kind of value",
    "is_subclass_of": "has the wrong kind of value",
    "needs_python_object": "must be a plain TOML value",
    "no_such_attribute": "unknown key (not allowed here; check the spelling)",
    "get_attribute_error": "cannot be read",
    "default_factory_not_called": "has no default here: set it",
    "missing_sentinel_error": "is required here: add it",
    "ellipsis_error": "must be a value",
    "arguments_type": "must be a table of arguments",
    "missing_argument": "is required here: add it",
    "missing_keyword_only_argument": "is required here: add it",
    "missing_positional_only_argument": "is required here: add it",
    "unexpected_keyword_argument": "unknown key (not allowed here; check the spelling)",
    "unexpected_positional_argument": "takes no further values",
    "multiple_argument_values": "is given twice",
    "uuid_type": "must be a UUID text", "uuid_parsing": "must be a UUID text",
    "uuid_version": "must be a UUID of another version",
    "url_type": "must be a URL text", "url_parsing": "must be a URL", "url_syntax_violation":
    "must be a well-formed URL", "url_too_long": "must be a shorter URL",
    "url_scheme": "must be a URL of another scheme",
}
_DATES = ("date", "time", "datetime", "timezone", "time_delta")


def shown(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (inputs can be long or nested)."""
    try:
        text = repr(value)
    except RecursionError:
        text = f"<{type(value).__name__} nested too deeply to show>"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def bound_text(value: float) -> str:
    """A range's end as a message shows it: short (``1e+09``, ``20000``) where that is the
    very number, else every digit it needs (``6.283185307179586``, not ``6.28319``, which
    would call a value just below the end out of range)."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    v = float(value)
    short = f"{v:g}"
    return short if float(short) == v else repr(v)


def _plural(n: Any, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def _number_words(t: str, ctx: dict, inp: Any) -> str:
    what = ""
    if isinstance(inp, bool):
        what = " (true/false is not a number)"
    elif isinstance(inp, str):
        what = " (text is not a number: write it without quotes)"
    if t == "greater_than":
        return f"must be a number > {ctx.get('gt')}{what}"
    if t == "greater_than_equal":
        return f"must be a number >= {ctx.get('ge')}{what}"
    if t == "less_than":
        return f"must be a number < {ctx.get('lt')}{what}"
    if t == "less_than_equal":
        return f"must be a number <= {ctx.get('le')}{what}"
    if t == "multiple_of":
        return f"must be a multiple of {ctx.get('multiple_of')}"
    if t == "finite_number":
        return "must be a finite number (not inf or nan)"
    if t == "int_from_float":
        return "must be a whole number (an integer)"
    if t in ("int_type", "int_parsing"):
        return f"must be an integer{what}"
    if t == "int_parsing_size":
        return "must be an integer of at most 19 digits"
    if t.startswith("decimal_"):
        return f"must be a number{what}"
    return f"must be a number{what}"


def _grammar(msg: str) -> str:
    """An unknown message of the library in the scene's grammar."""
    msg = re.sub(r"^Value error, ", "", msg)
    msg = re.sub(r"^Assertion failed, ", "", msg)
    msg = re.sub(r"\s*\[type=.*$", "", msg)
    msg = re.sub(r"^Input should (be|have)\b", r"must \1", msg)
    msg = msg.replace(" after validation", "")
    return msg[:1].lower() + msg[1:] if msg[:1].isupper() and not msg[:2].isupper() else msg


def validation_line(e: Mapping[str, Any], *, key: str, expected: str | None = None,
                    tags: Sequence[str] | None = None) -> tuple[str, str]:
    """``(key, text)`` of one validation error ``e`` in the scene's words: the key it is
    about (``key``, the dotted location; a union's discriminator is added to it) and
    "must be ...; received ...".  ``expected`` is what the key accepts when the caller
    knows it from the schema ("a finite number in (0, 20000]"); ``tags`` the names a
    union's discriminator takes (``design.type``)."""
    t = str(e.get("type", ""))
    ctx = dict(e.get("ctx") or {})
    inp = e.get("input")
    msg = str(e.get("msg", ""))
    received = True
    if t in NUMERIC_ERRORS or (t == "bool_type" and expected is not None):
        text = _number_words(t, ctx, inp)
        if expected is not None:
            text = "must be " + expected + (
                " (true/false is not a number)" if isinstance(inp, bool) else
                " (text is not a number: write it without quotes)" if isinstance(inp, str) else "")
    elif t in ("literal_error", "enum"):
        text = f"must be one of {ctx.get('expected', '?')}"
    elif t in ("too_short", "too_long"):
        n = ctx.get("min_length" if t == "too_short" else "max_length")
        most = "at least" if t == "too_short" else "at most"
        text = f"must hold {most} {_plural(n, 'value', 'values')}"
    elif t in ("string_too_short", "string_too_long", "bytes_too_short", "bytes_too_long"):
        n = ctx.get("min_length" if t.endswith("short") else "max_length")
        if t.endswith("short") and n == 1:
            text = "must not be empty"
        else:
            most = "at least" if t.endswith("short") else "at most"
            text = f"must have {most} {_plural(n, 'character', 'characters')}"
    elif t == "string_pattern_mismatch":
        text = f"must match the pattern {ctx.get('pattern')}"
    elif t in ("union_tag_invalid", "union_tag_not_found"):
        disc = str(ctx.get("discriminator", "type")).strip("'\"")
        key = f"{key}.{disc}" if key else disc
        names = ctx.get("expected_tags") or (", ".join(repr(x) for x in tags) if tags else "?")
        if t == "union_tag_not_found":
            text, received = f"is required (one of {names})", False
        else:
            text, inp = f"must be one of {names}", ctx.get("tag", inp)
    elif t in ("value_error", "assertion_error"):
        text = _grammar(msg)
        m = re.match(r"^([a-z_][a-z0-9_]*(?:\.[A-Za-z0-9_]+)*) (must|is|are) ", text)
        if m:  # a model-level check about one of its keys: name the key in full
            key = f"{key}.{m.group(1)}" if key else m.group(1)
            text = text[len(m.group(1)) + 1:]
    elif t in _WORDS:
        text = _WORDS[t]
        received = t not in ("missing", "missing_argument", "missing_keyword_only_argument",
                             "missing_positional_only_argument", "missing_sentinel_error",
                             "default_factory_not_called", "extra_forbidden")
    elif "discriminator" in ctx and isinstance(inp, dict):
        # a registry's own union ("kind must be one of [...]"): the key is the
        # discriminator, and the value received is its value
        disc = str(ctx["discriminator"]).strip("'\"")
        key = f"{key}.{disc}" if key else disc
        text = _grammar(msg)
        text = text[len(disc) + 1:] if text.startswith(disc + " ") else text
        if disc in inp:
            inp = inp[disc]
        else:
            text, received = f"is required ({text})", False
    elif t.startswith(_DATES):
        text = "must be a date or time (ISO 8601) in the allowed range"
    else:
        text = _grammar(msg)
    if received and not isinstance(inp, dict) and "received" not in text:
        text += f"; received {shown(inp)}"
    for phrase in LIBRARY_WORDING:  # the last resort: never the library's own words
        text = text.replace(phrase, "")
    return key, text
