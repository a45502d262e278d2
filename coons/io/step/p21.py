"""ISO 10303-21 (STEP Part 21) exchange-file parser: text -> header records and a table of entity instances.

:func:`parse` reads the clear-text encoding of ISO 10303-21 (editions 1-3): the ``HEADER``
section and one or more ``DATA`` sections, simple instances ``#12 = NAME(params);`` and complex
ones ``#12 = (A(...) B(...) C(...));``.  Parameters become Python values (table below); nothing is
interpreted beyond the syntax: the mapping of entity types to geometry is
:mod:`coons.io.step.schema`.  The module deliberately does not read ``ANCHOR``, ``REFERENCE`` or
``SIGNATURE`` sections (edition 3 extensions rarely written by CAD systems), does not check
parameter counts or types against an EXPRESS schema, and does not resolve references while
parsing: :meth:`P21File.get` does, and reports a dangling ``#ref`` there.

Parameter values::

    'text' (with '' and \\X2\\...\\X0\\ etc. decoded)   str
    123, -4                                           int
    1., -2.5E-3                                       float
    #42                                               Ref(42)
    .T. / .F.                                         True / False
    .UNSPECIFIED.                                     Enum('UNSPECIFIED')  (.U. is Enum('U'))
    $                                                 None
    *                                                 DERIVED
    (a, b, ...)                                       tuple
    LENGTH_MEASURE(1.)                                Typed('LENGTH_MEASURE', (1.0,))
    "0FF"                                             Binary('0FF')

Algorithm.  *Fast path* (files as CAD systems write them): the header goes through the general
parser; in the DATA sections one anchored regular expression (atomic groups, possessive
quantifiers) matches and validates each whole simple instance ``#id = NAME( args );`` at C speed
when its arguments have the common shapes (numbers, references, enumerations, ``$``, ``*``,
plain strings, lists of those up to two levels deep), and such instances keep their argument
text until :attr:`Entity.params` is first read (:meth:`Entity.real_triple` reads a point's or
direction's three numbers straight from it) (entities a reader never visits, such as the file's own p-curves, are never
converted).  Every other instance (complex, typed or nested parameters, escaped strings,
binaries) is parsed at once by the general parser, and anything the fast path cannot follow
(comments, syntax errors, edition-3 sections) sends the whole file to the general parser, so
errors are reported exactly as below.  *General parser*: one regular expression tokenises the
text (``re.findall``; comments, strings and every other token in a single pass), then a loop
over the tokens builds the instances with an explicit stack for nested lists, bounded by
:data:`MAX_DEPTH`, so that no input can recurse or loop without bound.  The two paths give
identical values and line numbers (``tests/io/test_p21.py`` compares them).  Every malformed input raises :class:`~coons.errors.StepError` with the
entity id and the 1-based line where it was found; a file that lacks its ``ENDSEC`` or
``END-ISO-10303-21;`` (a truncated file) is refused rather than read in part, and so is a
duplicated entity id.

Reference: ISO 10303-21:2016, *Clear text encoding of the exchange structure*, §5 (tokens),
§6 (string control directives), §8-9 (header and data sections).
"""

from __future__ import annotations

import os
import re
from typing import Any, Iterator

from coons.errors import StepError

__all__ = ["parse", "parse_file", "P21File", "Entity", "Ref", "Enum", "Typed", "Binary", "DERIVED", "MAX_DEPTH"]

#: Deepest nesting of parameter lists accepted (B-spline surfaces need 3; real files stay below 10).
MAX_DEPTH = 32


class Ref:
    """An entity reference ``#id``."""

    __slots__ = ("id",)

    def __init__(self, id: int) -> None:
        self.id = id

    def __repr__(self) -> str:
        return f"#{self.id}"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Ref) and other.id == self.id

    def __hash__(self) -> int:
        return hash(("Ref", self.id))


class Enum:
    """An enumeration value ``.NAME.`` other than the logicals ``.T.`` and ``.F.``."""

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return f".{self.name}."

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Enum) and other.name == self.name

    def __hash__(self) -> int:
        return hash(("Enum", self.name))


class Typed:
    """A typed parameter ``NAME(params)`` such as ``LENGTH_MEASURE(1.)``."""

    __slots__ = ("name", "params")

    def __init__(self, name: str, params: tuple) -> None:
        self.name = name
        self.params = params

    def __repr__(self) -> str:
        return f"{self.name}{self.params!r}"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Typed) and other.name == self.name and other.params == self.params

    def __hash__(self) -> int:
        return hash(("Typed", self.name, self.params))


class Binary:
    """A binary value ``"0FF"`` (hexadecimal digits, the first giving the count of unused bits)."""

    __slots__ = ("hex",)

    def __init__(self, hex: str) -> None:
        self.hex = hex

    def __repr__(self) -> str:
        return f'"{self.hex}"'

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Binary) and other.hex == self.hex

    def __hash__(self) -> int:
        return hash(("Binary", self.hex))


class _Derived:
    __slots__ = ()

    def __repr__(self) -> str:
        return "*"


#: The derived-value marker ``*``.
DERIVED = _Derived()


class Entity:
    """One entity instance of a DATA section.

    Attributes
    ----------
    id : int
    name : str
        The type name of a simple instance; for a complex instance the names of its parts
        joined by ``'+'`` (e.g. ``'BOUNDED_CURVE+B_SPLINE_CURVE+...'``).
    params : tuple
        The parameters of a simple instance; ``()`` for a complex instance.
    parts : dict[str, tuple] or None
        Complex instances: each partial type's parameters, in file order; None for a simple one.
    line : int
        1-based line where the instance starts.
    """

    __slots__ = ("id", "name", "_params", "_raw", "parts", "line")

    def __init__(self, id: int, name: str, params: tuple, parts: dict | None, line: int, raw: str | None = None) -> None:
        # raw: the argument text of a simple instance (already validated) parsed on first use
        self.id = id
        self.name = name
        self._params = params
        self._raw = raw
        self.parts = parts
        self.line = line

    @property
    def params(self) -> tuple:
        if self._raw is not None:
            self._params = _deferred_args(self._raw, self.id, self.line)
            self._raw = None
        return self._params

    def real_triple(self) -> tuple[float, float, float] | None:
        """``(x, y, z)`` when the instance is an unread simple instance of the form ``'name', (x, y, z)``
        with three numbers (a CARTESIAN_POINT or DIRECTION as CAD systems write them), else None.

        A shortcut for readers of many points: the numbers are converted without building
        :attr:`params` (which stays available and equal).
        """
        if self._raw is None:
            return None
        m = _REAL_TRIPLE.fullmatch(self._raw)
        if m is None:
            return None
        return float(m.group(1)), float(m.group(2)), float(m.group(3))

    @property
    def is_complex(self) -> bool:
        return self.parts is not None

    def has_type(self, name: str) -> bool:
        """Whether the instance is of type ``name`` (a simple instance's name or one of a complex one's parts)."""
        return self.name == name if self.parts is None else name in self.parts

    def __repr__(self) -> str:
        if self.parts is None:
            return f"#{self.id}={self.name}{self.params!r}"
        return f"#{self.id}=({' '.join(f'{k}{v!r}' for k, v in self.parts.items())})"


class P21File:
    """A parsed exchange file.

    Attributes
    ----------
    header : list of (str, tuple)
        The header records (``FILE_DESCRIPTION``, ``FILE_NAME``, ``FILE_SCHEMA`` ...) in file order.
    entities : dict[int, Entity]
        Every instance of every DATA section, by id.
    schemas : tuple of str
        The schema names of ``FILE_SCHEMA`` (empty when the header has none).
    """

    __slots__ = ("header", "entities", "schemas")

    def __init__(self, header: list, entities: dict) -> None:
        self.header = header
        self.entities = entities
        schemas: tuple = ()
        for name, params in header:
            if name == "FILE_SCHEMA" and params and isinstance(params[0], tuple):
                schemas = tuple(s for s in params[0] if isinstance(s, str))
        self.schemas = schemas

    def __len__(self) -> int:
        return len(self.entities)

    def __iter__(self) -> Iterator[Entity]:
        return iter(self.entities.values())

    def get(self, ref: Any, referrer: Entity | None = None) -> Entity:
        """The entity a :class:`Ref` points to.

        Raises
        ------
        StepError
            ``ref`` is not a reference, or it points to no entity (a dangling reference); the error
            names the referring entity and its line when ``referrer`` is given.
        """
        where = {} if referrer is None else {"entity_id": referrer.id, "line": referrer.line}
        if not isinstance(ref, Ref):
            raise StepError(f"expected an entity reference #id, got {ref!r}", **where)
        ent = self.entities.get(ref.id)
        if ent is None:
            raise StepError(f"reference #{ref.id} points to no entity of the file (dangling reference)", **where)
        return ent

    def of_type(self, name: str) -> list[Entity]:
        """Every instance of type ``name`` (simple or as a part of a complex instance), in id order."""
        return sorted((e for e in self.entities.values() if e.has_type(name)), key=lambda e: e.id)

    def dangling(self) -> list[tuple[int, int]]:
        """``(entity id, missing id)`` for every reference to a missing entity (the whole file)."""
        out = []
        ents = self.entities

        def walk(x: Any, eid: int) -> None:
            stack = [x]
            while stack:
                y = stack.pop()
                if isinstance(y, Ref):
                    if y.id not in ents:
                        out.append((eid, y.id))
                elif isinstance(y, tuple):
                    stack.extend(y)
                elif isinstance(y, Typed):
                    stack.extend(y.params)

        for e in ents.values():
            walk(e.params if e.parts is None else tuple(e.parts.values()), e.id)
        return out


# ---------------------------------------------------------------------- tokens
# Order matters: comments and strings first (they may contain anything), the file delimiters
# (which contain '-') before keywords, enumerations before numbers ('.5' vs '.T.').
_TOKEN = re.compile(
    r"""/\*.*?(?:\*/|\Z)"""              # comment (an unterminated one runs to the end: linear time)
    r"""|'[^']*(?:''[^']*)*(?:'|\Z)"""    # string (likewise)
    r"""|\n"""                           # line break (counted)
    r"""|END-ISO-10303-21|ISO-10303-21"""
    r"""|\#\d+"""                        # reference or instance name
    r"""|\.[A-Za-z_][A-Za-z0-9_]*\."""   # enumeration / logical
    r"""|[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"""  # integer or real
    r"""|!?[A-Za-z_][A-Za-z0-9_]*"""     # keyword (standard or user-defined)
    r"""|"[0-9A-Fa-f]*\""""              # binary
    r"""|[(),;=$*]"""                    # punctuation
    r"""|\S""",                          # anything else: an error, reported with its line
    re.DOTALL,
)
_PUNCT = frozenset("(),;=$*")


def _tokens(text: str) -> tuple[list[str], list[int]]:
    """Tokens without comments and line breaks, and the 1-based line of each."""
    raw = _TOKEN.findall(text)
    toks: list[str] = []
    lines: list[int] = []
    line = 1
    append, lappend = toks.append, lines.append
    for t in raw:
        c = t[0]
        if c == "\n":
            line += 1
        elif c == "/" and len(t) > 1:  # a comment ('/' alone is a stray character)
            if not t.endswith("*/") or len(t) < 4:
                raise StepError("unterminated comment '/*' (no closing '*/')", line=line)
            line += t.count("\n")
        else:
            append(t)
            lappend(line)
            if c == "'":
                line += t.count("\n")
    return toks, lines


_DIRECTIVE = re.compile(r"\\X2\\((?:[0-9A-Fa-f]{4})*)\\X0\\|\\X4\\((?:[0-9A-Fa-f]{8})*)\\X0\\|\\X\\([0-9A-Fa-f]{2})|\\S\\(.)|\\P[A-I]\\|\\\\|\\", re.DOTALL)


def _string(tok: str, line: int) -> str:
    """Decode a string token (quotes, ``''``, line breaks and the control directives of ISO 10303-21 §6.4.3)."""
    s = tok[1:-1]
    if "\n" in s or "\r" in s:
        s = s.replace("\r", "").replace("\n", "")  # physical line breaks are not part of a string
    if "''" in s:
        s = s.replace("''", "'")
    if "\\" not in s:
        return s

    def sub(m: re.Match) -> str:
        x2, x4, x, sc = m.group(1), m.group(2), m.group(3), m.group(4)
        if x2 is not None:
            return "".join(chr(int(x2[i:i + 4], 16)) for i in range(0, len(x2), 4)).encode(
                "utf-16", "surrogatepass").decode("utf-16", "replace")
        if x4 is not None:
            cps = [int(x4[i:i + 8], 16) for i in range(0, len(x4), 8)]
            if any(cp > 0x10FFFF for cp in cps):
                raise StepError(f"string {tok[:40]!r}: \\X4\\ code point above U+10FFFF", line=line)
            return "".join(chr(cp) for cp in cps)
        if x is not None:
            return chr(int(x, 16))
        if sc is not None:
            return chr(ord(sc) + 128) if ord(sc) < 128 else sc
        g = m.group(0)
        if g == "\\\\":
            return "\\"
        if g.startswith("\\P"):
            return ""  # code page switch: the text is decoded as Unicode already
        raise StepError(f"string {tok[:40]!r}: a backslash must start a control directive (\\X2\\, \\X\\, \\S\\, \\\\ ...)", line=line)

    return _DIRECTIVE.sub(sub, s)


# ---------------------------------------------------------------------- parser
class _Parser:
    __slots__ = ("toks", "lines", "i", "n")

    def __init__(self, toks: list[str], lines: list[int]) -> None:
        self.toks = toks
        self.lines = lines
        self.i = 0
        self.n = len(toks)

    def line(self, i: int | None = None) -> int:
        i = self.i if i is None else i
        if not self.lines:
            return 1
        return self.lines[min(i, self.n - 1)]

    def error(self, message: str, entity_id: int | None = None, at: int | None = None) -> StepError:
        return StepError(message, entity_id=entity_id, line=self.line(at))

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < self.n else None

    def expect(self, tok: str, what: str, entity_id: int | None = None) -> None:
        got = self.peek()
        if got != tok:
            found = "end of file" if got is None else repr(got)
            raise self.error(f"expected {tok!r} {what}, found {found}", entity_id)
        self.i += 1

    def params(self, eid: int | None) -> tuple:
        """Parse ``( ... )`` at the current token (an explicit stack: no recursion)."""
        toks, n = self.toks, self.n
        i = self.i
        if i >= n or toks[i] != "(":
            raise self.error(f"expected '(' opening a parameter list, found {toks[i] if i < n else 'end of file'!r}", eid, i)
        i += 1
        stack: list[tuple[str | None, list]] = [(None, [])]
        cur = stack[-1][1]
        need_value = False  # after ',' a value is required; right after '(' a ')' is allowed
        after_value = False
        while True:
            if i >= n:
                raise self.error("unexpected end of file inside a parameter list (truncated file?)", eid, n - 1)
            t = toks[i]
            i += 1
            c = t[0]
            if c == ")":
                if need_value:
                    raise self.error("expected a parameter after ',', found ')'", eid, i - 1)
                name, items = stack.pop()
                value: Any = tuple(items) if name is None else Typed(name, tuple(items))
                if not stack:
                    self.i = i
                    return value
                cur = stack[-1][1]
                cur.append(value)
                after_value, need_value = True, False
                continue
            if c == ",":
                if not after_value:
                    raise self.error("expected a parameter before ','", eid, i - 1)
                after_value, need_value = False, True
                continue
            if after_value:
                raise self.error(f"expected ',' or ')' after a parameter, found {t!r}", eid, i - 1)
            if c == "(":
                if len(stack) >= MAX_DEPTH:
                    raise self.error(f"parameter lists nested deeper than {MAX_DEPTH}", eid, i - 1)
                stack.append((None, []))
                cur = stack[-1][1]
                need_value = False
                continue
            if c == "#" and len(t) > 1:
                cur.append(Ref(int(t[1:])))
            elif c == "'" and (len(t) - 1 - len(t[1:].rstrip("'"))) % 2 == 1:  # odd: the last quote closes
                cur.append(_string(t, self.lines[i - 1]))
            elif c == "." and len(t) > 1 and (t[1].isalpha() or t[1] == "_"):
                e = t[1:-1]
                cur.append(True if e == "T" else False if e == "F" else Enum(e))
            elif c.isdigit() or c in "+-.":
                if t in "+-.":
                    raise self.error(f"unexpected character {t!r} in a parameter list", eid, i - 1)
                cur.append(float(t) if ("." in t or "e" in t or "E" in t) else int(t))
            elif c == "$":
                cur.append(None)
            elif c == "*":
                cur.append(DERIVED)
            elif c.isalpha() or c == "_" or c == "!":
                if i >= n or toks[i] != "(":
                    raise self.error(f"typed parameter {t} must be followed by '('", eid, i - 1)
                if len(stack) >= MAX_DEPTH:
                    raise self.error(f"parameter lists nested deeper than {MAX_DEPTH}", eid, i - 1)
                i += 1
                stack.append((t, []))
                cur = stack[-1][1]
                need_value = False
                continue
            elif c == '"' and len(t) > 1:
                cur.append(Binary(t[1:-1]))
            elif c == "'":
                raise self.error("unterminated string (a quote without its closing quote)", eid, i - 1)
            else:
                raise self.error(f"unexpected token {t!r} in a parameter list", eid, i - 1)
            after_value, need_value = True, False

    def header(self) -> list:
        out = []
        while True:
            t = self.peek()
            if t is None:
                raise self.error("unexpected end of file in the HEADER section (missing ENDSEC; truncated file?)")
            if t == "ENDSEC":
                self.i += 1
                self.expect(";", "after ENDSEC")
                return out
            if not (t[0].isalpha() or t[0] in "_!"):
                raise self.error(f"expected a header entity or ENDSEC, found {t!r}")
            self.i += 1
            out.append((t, self.params(None)))
            self.expect(";", f"after header entity {t}")

    def data(self, entities: dict) -> None:
        while True:
            t = self.peek()
            if t is None:
                raise self.error("unexpected end of file in a DATA section (missing ENDSEC; truncated file?)")
            if t == "ENDSEC":
                self.i += 1
                self.expect(";", "after ENDSEC")
                return
            self.instance(entities)

    def instance(self, entities: dict) -> None:
        """Parse one instance ``#id = ... ;`` at the current token into ``entities``."""
        toks, lines = self.toks, self.lines
        i = self.i
        t = self.peek()
        if t is None:
            raise self.error("unexpected end of file in a DATA section (missing ENDSEC; truncated file?)")
        if t[0] != "#" or len(t) < 2:
            raise self.error(f"expected an entity instance '#id = ...;' or ENDSEC, found {t!r}")
        eid = int(t[1:])
        line = lines[i]
        if eid in entities:
            raise StepError(f"duplicate entity id #{eid} (first defined on line {entities[eid].line})",
                            entity_id=eid, line=line)
        self.i += 1
        self.expect("=", "after the instance name", eid)
        t = self.peek()
        if t is None:
            raise self.error("unexpected end of file after '='", eid)
        if t == "(":  # complex instance: a list of partial types
            self.i += 1
            parts: dict[str, tuple] = {}
            while True:
                t = self.peek()
                if t == ")":
                    self.i += 1
                    break
                if t is None or not (t[0].isalpha() or t[0] in "_!"):
                    found = "end of file" if t is None else repr(t)
                    raise self.error(f"expected a partial entity type in a complex instance, found {found}", eid)
                if t in parts:
                    raise self.error(f"partial type {t} appears twice in a complex instance", eid)
                self.i += 1
                parts[t] = self.params(eid)
            if not parts:
                raise self.error("empty complex instance '()'", eid)
            entities[eid] = Entity(eid, "+".join(parts), (), parts, line)
        elif t[0].isalpha() or t[0] in "_!":
            self.i += 1
            entities[eid] = Entity(eid, t, self.params(eid), None, line)
        else:
            raise self.error(f"expected an entity type name after '=', found {t!r}", eid)
        if self.i >= self.n or toks[self.i] != ";":
            raise self.error(f"expected ';' ending the instance, found {self.peek() or 'end of file'!r}", eid)
        self.i += 1

    def file(self) -> P21File:
        self.expect("ISO-10303-21", "at the start of the file (not an ISO 10303-21 file)")
        self.expect(";", "after ISO-10303-21")
        self.expect("HEADER", "(the HEADER section must come first)")
        self.expect(";", "after HEADER")
        header = self.header()
        entities: dict[int, Entity] = {}
        n_data = 0
        while True:
            t = self.peek()
            if t == "DATA":
                self.i += 1
                if self.peek() == "(":
                    self.params(None)  # edition 3: DATA('name', ('schema')); the name is not needed
                self.expect(";", "after DATA")
                self.data(entities)
                n_data += 1
            elif t == "END-ISO-10303-21":
                self.i += 1
                self.expect(";", "after END-ISO-10303-21")
                break
            elif t is None:
                raise self.error("unexpected end of file: missing END-ISO-10303-21; (truncated file?)")
            elif t in ("ANCHOR", "REFERENCE", "SIGNATURE"):
                raise self.error(f"{t} sections (ISO 10303-21 edition 3) are not supported")
            else:
                raise self.error(f"expected DATA or END-ISO-10303-21, found {t!r}")
        if self.i < self.n:
            raise self.error(f"unexpected {self.toks[self.i]!r} after END-ISO-10303-21;")
        if n_data == 0:
            raise self.error("the file has no DATA section")
        return P21File(header, entities)


# ---------------------------------------------------------------------- fast path
# Well-formed files written by CAD systems are read without tokenising the DATA section: one
# regular expression (_FAST_DEFERRED) matches each whole instance ``#id = NAME( args );`` whose
# arguments have the common shapes (atoms and lists of atoms up to two levels deep, the grammar
# _DEFERRABLE) at C speed, and those are converted with str methods only when first read
# (_deferred_args).  Anything else -- complex instances, typed parameters, strings with escapes,
# lists nested three deep, binaries -- is handed instance by instance to the general parser above, and a
# file the fast path cannot follow at all (a syntax error, an unusual section) is re-read by the
# general parser from the start, which reports the error with its line.  Both paths produce the
# same values (tests/io/test_p21.py compares them).

class _Irregular(Exception):
    """The fast path cannot read this input: use the general path."""


_WS = re.compile(r"\s")
#: The extent of any instance (strings may hold anything but unpaired quotes); parsed by the general parser.
_ANY_ENTITY = re.compile(r"""\s*(\#[0-9]+\s*=(?:[^;'/]|'[^']*')*;)""")
_DATA_OPEN = re.compile(r"\s*DATA\s*;")
_END_SEC = re.compile(r"\s*ENDSEC\s*;")
_END_FILE = re.compile(r"\s*END-ISO-10303-21\s*;\s*\Z")
_NUM = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
#: The arguments ``'name', (x, y, z)`` of a point or direction (see Entity.real_triple).
_REAL_TRIPLE = re.compile(rf"\s*'[^'\\\r\n]*'\s*,\s*\(\s*({_NUM})\s*,\s*({_NUM})\s*,\s*({_NUM})\s*\)\s*")
#: Items of validated arguments without strings or white space: a one-level list, or an atom.
_LEVEL1_ITEMS = re.compile(r"\(([^()]*)\)|([^,()]+)")
# The argument grammar the fast path defers: atoms (numbers, references, enumerations, $, *, plain
# strings) and lists of atoms up to two levels deep, comma separated, optional white space between
# tokens.  Atomic groups and possessive quantifiers: the grammar is unambiguous (every token's kind
# is fixed by its first character, a list's depth by its parentheses), so giving back what a token
# matched never finds another match, and not trying it halves the matching time.
_PNUM = r"[+-]?+(?:[0-9]++\.?+[0-9]*+|\.[0-9]++)(?:[eE][+-]?+[0-9]++)?+"
_STR = r"'[^'\\\r\n]*+'(?!')"
_ATOM = rf"(?>\#[0-9]++|{_PNUM}|\.[A-Za-z_][A-Za-z0-9_]*+\.|\$|\*|{_STR})"
_LIST1 = rf"\(\s*+(?:{_ATOM}(?:\s*+,\s*+{_ATOM})*+)?+\s*+\)"
_ARG1 = rf"(?>{_ATOM}|{_LIST1})"
#: Lists of atoms and one-level lists (a B-spline surface's control point grid, its weights).
_LIST2 = rf"\(\s*+(?:{_ARG1}(?:\s*+,\s*+{_ARG1})*+)?+\s*+\)"
_ARG2 = rf"(?>{_ATOM}|{_LIST1}|{_LIST2})"
_DEFERRABLE = re.compile(rf"\s*+(?:{_ARG2}(?:\s*+,\s*+{_ARG2})*+)?+\s*+")
#: A whole simple instance whose arguments match :data:`_DEFERRABLE`: one match finds and
#: validates it.  It ends where :data:`_ANY_ENTITY` would (at the first ``;`` outside strings,
#: which neither grammar admits elsewhere), so an instance it does not match goes whole to the
#: general parser.
_FAST_DEFERRED = re.compile(
    rf"""\s*+(\#([0-9]++)\s*+=\s*+([A-Za-z_][A-Za-z0-9_]*+)\s*+\(({_DEFERRABLE.pattern})\)\s*+;)""")
#: An opening parenthesis inside a list: the arguments nest two levels deep.
_NESTED = re.compile(r"\([^()]*\(")
_NESTED_TOKENS = re.compile(r"[(),]|[^(),]+")


def _deferred_args(raw: str, eid: int, line: int) -> tuple:
    """Parse argument text that matched :data:`_DEFERRABLE` (so it is valid: no checks needed here)."""
    head: tuple = ()
    if "'" in raw:
        a = raw.lstrip()
        j = a.find("'", 1)
        if a[0] != "'" or "'" in a[j + 1:]:  # strings after the first one: the general parser
            toks, _ = _tokens("(" + raw + ")")
            return _Parser(toks, [line] * len(toks)).params(eid)
        head = (a[1:j],)
        raw = a[j + 1:]
    # outside strings valid arguments have no white space inside a token: dropping it is safe
    if _WS.search(raw):
        raw = "".join(raw.split())
    if head:
        if not raw:
            return head
        raw = raw[1:]  # the comma after the string
    if not raw:
        return head
    if "(" not in raw:
        return head + tuple(map(_valid_scalar, raw.split(",")))
    if _NESTED.search(raw):
        return head + _nested_args(raw)
    out = list(head)
    for inner, item in _LEVEL1_ITEMS.findall(raw):
        if item:
            out.append(_valid_scalar(item))
        else:
            out.append(tuple(map(_valid_scalar, inner.split(","))) if inner else ())
    return tuple(out)


def _nested_args(raw: str) -> tuple:
    """Arguments without strings or white space nesting lists up to :data:`_LIST2` (validated: no checks)."""
    stack: list[list] = [[]]
    for tok in _NESTED_TOKENS.findall(raw):
        if tok == "(":
            stack.append([])
        elif tok == ")":
            done = tuple(stack.pop())
            stack[-1].append(done)
        elif tok != ",":
            stack[-1].append(_valid_scalar(tok))
    return tuple(stack[0])


def _valid_scalar(s: str) -> Any:
    """The value of a token known to be a valid atom (number, reference, enumeration, $, *)."""
    c = s[0]
    if c == "#":
        return Ref(int(s[1:]))
    if c == "." and s[-1] == "." and len(s) > 2 and not s[1].isdigit():
        e = s[1:-1]
        return True if e == "T" else False if e == "F" else Enum(e)
    if c == "$":
        return None
    if c == "*":
        return DERIVED
    return float(s) if ("." in s or "e" in s or "E" in s) else int(s)


def _parse_fast(text: str) -> P21File | None:
    """The fast path (see above); raises :class:`_Irregular` (or StepError/ValueError) to hand over."""
    # the header, with the general tokeniser (it is short): tokens up to its ENDSEC ;
    toks: list[str] = []
    lines: list[int] = []
    line, pos = 1, None
    for m in _TOKEN.finditer(text):
        t = m.group()
        c = t[0]
        if c == "\n":
            line += 1
            continue
        if c == "/" and len(t) > 1:
            raise _Irregular("comment in the header")
        toks.append(t)
        lines.append(line)
        if c == "'":
            line += t.count("\n")
        if t == ";" and len(toks) >= 2 and toks[-2] == "ENDSEC":
            pos = m.end()
            break
    if pos is None:
        raise _Irregular("no header ENDSEC")
    p = _Parser(toks, lines)
    p.expect("ISO-10303-21", "")
    p.expect(";", "")
    p.expect("HEADER", "")
    p.expect(";", "")
    header = p.header()
    if p.i != p.n:
        raise _Irregular("header")
    entities: dict[int, Entity] = {}
    count = text.count
    deferred = _FAST_DEFERRED.match
    n_data = 0
    while True:
        m = _DATA_OPEN.match(text, pos)
        if m is None:
            break
        line += count("\n", pos, m.end())
        pos = m.end()
        n_data += 1
        while True:
            m = deferred(text, pos)
            if m is not None:  # valid: parsed when first used
                start, end = m.start(1), m.end()
                line += count("\n", pos, start)
                eid = int(m.group(2))
                if eid in entities:
                    raise _Irregular("duplicate id")
                entities[eid] = Entity(eid, m.group(3), (), None, line, m.group(4))
                line += count("\n", start, end)
                pos = end
                continue
            m = _ANY_ENTITY.match(text, pos)
            if m is not None:
                start = m.start(1)
                line += count("\n", pos, start)
                _general_instance(text, start, m.end(), line, entities)
                line += count("\n", start, m.end())
                pos = m.end()
                continue
            m = _END_SEC.match(text, pos)
            if m is None:
                raise _Irregular("DATA section")
            line += count("\n", pos, m.end())
            pos = m.end()
            break
    if n_data == 0 or _END_FILE.match(text, pos) is None:
        raise _Irregular("file end")
    return P21File(header, entities)


def _general_instance(text: str, start: int, end: int, line: int, entities: dict) -> None:
    """One instance ``text[start:end]`` (starting on ``line``) through the general parser."""
    toks, lines = _tokens(text[start:end])
    if line != 1:
        lines = [k + line - 1 for k in lines]
    p = _Parser(toks, lines)
    p.instance(entities)
    if p.i != p.n:
        raise _Irregular("instance")


def parse(text: str | bytes) -> P21File:
    """Parse the text of an ISO 10303-21 exchange file.

    Parameters
    ----------
    text : str or bytes
        Bytes are decoded as UTF-8, or as Latin-1 when they are not valid UTF-8 (STEP text is
        ASCII; non-ASCII bytes appear only in non-conforming strings).

    Returns
    -------
    P21File

    Raises
    ------
    StepError
        Any syntax error (with entity id and line), a duplicated id, a truncated file (missing
        ``ENDSEC`` or ``END-ISO-10303-21;``), lists nested deeper than :data:`MAX_DEPTH`.

    Examples
    --------
    >>> f = parse("ISO-10303-21;HEADER;ENDSEC;DATA;#1=CARTESIAN_POINT('',(0.,1.5,-2));ENDSEC;END-ISO-10303-21;")
    >>> f.entities[1].name, f.entities[1].params
    ('CARTESIAN_POINT', ('', (0.0, 1.5, -2)))
    """
    if isinstance(text, (bytes, bytearray, memoryview)):
        raw = bytes(text)
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            text = raw.decode("latin-1")
    if not isinstance(text, str):
        raise StepError(f"parse needs str or bytes, got {type(text).__name__}")
    try:
        fast = _parse_fast(text)
    except (_Irregular, IndexError, ValueError, OverflowError, UnicodeError, StepError):
        fast = None  # the general path below reads it, or reports the error with its line
    if fast is not None:
        return fast
    toks, lines = _tokens(text)
    try:
        return _Parser(toks, lines).file()
    except (ValueError, OverflowError, UnicodeError) as exc:  # int()/float()/chr() of a malformed token
        raise StepError(f"malformed token: {exc}") from None


def parse_file(path: str | os.PathLike) -> P21File:
    """Read and :func:`parse` a file.

    Raises
    ------
    StepError
        The file cannot be read, or as :func:`parse`.
    """
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise StepError(f"cannot read {os.fspath(path)!r}: {exc.strerror or exc}") from None
    return parse(data)
