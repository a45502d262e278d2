"""ISO 10303-21 parser: values, complex instances, line numbers and every error branch."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import StepError
from coons.io.step.p21 import DERIVED, MAX_DEPTH, Binary, Enum, Ref, Typed, parse, parse_file

DATA = Path(__file__).resolve().parents[1] / "data"
CORPUS = sorted(DATA.glob("*.step"))


def wrap(data: str, header: str = "FILE_DESCRIPTION(('x'),'2;1');FILE_SCHEMA(('AP214'));") -> str:
    return f"ISO-10303-21;\nHEADER;\n{header}\nENDSEC;\nDATA;\n{data}\nENDSEC;\nEND-ISO-10303-21;\n"


def test_values_of_every_kind():
    f = parse(wrap(
        "#1=THING('it''s',-3,2.5E-3,1.,.5,#22,.T.,.F.,.U.,.UNSPECIFIED.,$,*,(1,(2,3),()),"
        "LENGTH_MEASURE(1.),\"0FF\",!USER_TYPE(4));"
    ))
    p = f.entities[1].params
    assert p[0] == "it's"
    assert p[1] == -3 and isinstance(p[1], int)
    assert p[2] == 2.5e-3 and p[3] == 1.0 and isinstance(p[3], float) and p[4] == 0.5
    assert p[5] == Ref(22)
    assert p[6] is True and p[7] is False and p[8] == Enum("U") and p[9] == Enum("UNSPECIFIED")
    assert p[10] is None and p[11] is DERIVED
    assert p[12] == (1, (2, 3), ())
    assert p[13] == Typed("LENGTH_MEASURE", (1.0,))
    assert p[14] == Binary("0FF")
    assert p[15] == Typed("!USER_TYPE", (4,))
    assert f.schemas == ("AP214",)
    assert f.header[0][0] == "FILE_DESCRIPTION"


def test_string_encodings():
    f = parse(wrap(r"#1=S('\X2\00E400FC\X0\','\X\E9','\S\a','a\\b','\X4\0001F600\X0\','ab" "\n" r"cd','\PA\x');"))
    assert f.entities[1].params == ("äü", "é", "á", "a\\b", "\U0001F600", "abcd", "x")


def test_complex_instance_comments_lines_and_several_data_sections():
    text = (
        "ISO-10303-21;\nHEADER;\n/* a comment\nover two lines */\nFILE_SCHEMA(('X'));\nENDSEC;\n"
        "DATA;\n#1=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );\nENDSEC;\n"
        "DATA;\n#2 = POINT(\n#1);\nENDSEC;\nEND-ISO-10303-21;"
    )
    f = parse(text)
    e = f.entities[1]
    assert e.is_complex and e.name == "LENGTH_UNIT+NAMED_UNIT+SI_UNIT"
    assert e.parts["SI_UNIT"] == (Enum("MILLI"), Enum("METRE"))
    assert e.has_type("NAMED_UNIT") and not e.has_type("POINT")
    assert e.line == 8 and f.entities[2].line == 11
    assert f.get(f.entities[2].params[0]) is e
    assert [x.id for x in f.of_type("SI_UNIT")] == [1]


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.name)
def test_corpus_parses_without_dangling_references(path):
    f = parse_file(path)
    assert len(f) > 1000
    assert f.dangling() == []
    assert f.of_type("ADVANCED_FACE")


@given(st.lists(st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=False, allow_infinity=False)),
                min_size=1, max_size=20))
def test_numbers_round_trip(values):
    text = ",".join(repr(v) if isinstance(v, int) else f"{v:.17E}" for v in values)
    got = parse(wrap(f"#5=N(({text}));")).entities[5].params[0]
    assert list(got) == [float(v) if isinstance(v, float) else v for v in values]


# ---------------------------------------------------------------------- errors
@pytest.mark.parametrize("text, match", [
    ("HEADER;ENDSEC;", r"expected 'ISO-10303-21'"),
    (wrap("#1=A(1);#2=B(2,3);").split("3);")[0], r"end of file inside a parameter list \(truncated file\?\)"),
    (wrap("#1=A(1);")[:-19], r"missing END-ISO-10303-21; \(truncated file\?\)"),
    (wrap("#1=A(1);")[:-26], r"missing ENDSEC; truncated file\?"),
    (wrap("#1=A(1);").replace("ENDSEC;\nEND", "END"), r"expected an entity instance"),
    ("ISO-10303-21;HEADER;FILE_SCHEMA(('X'));", r"missing ENDSEC"),
    ("ISO-10303-21;HEADER;ENDSEC;END-ISO-10303-21;", r"no DATA section"),
    (wrap("#1=A(1);#1=B(2);"), r"duplicate entity id #1 \(first defined on line 6\)"),
    (wrap("#1=A(1,);"), r"expected a parameter after ','"),
    (wrap("#1=A(,1);"), r"expected a parameter before ','"),
    (wrap("#1=A(1 2);"), r"expected ',' or '\)' after a parameter"),
    (wrap("#1=A(1);;"), r"expected an entity instance"),
    (wrap("#1=A(1)"), r"expected ';' ending the instance"),
    (wrap("#1=A('abc);"), r"unterminated string"),
    (wrap("#1=A(@);"), r"unexpected token '@'"),
    (wrap("#1=A(B);"), r"typed parameter B must be followed by '\('"),
    (wrap("#1=A(" + "(" * (MAX_DEPTH + 5) + ")" * (MAX_DEPTH + 5) + ");"), r"nested deeper than"),
    (wrap("#1=();"), r"empty complex instance"),
    (wrap("#1=(A()A());"), r"appears twice"),
    (wrap("#1=(A() 5);"), r"expected a partial entity type"),
    (wrap("#1=5;"), r"expected an entity type name"),
    (wrap("#1 A(1);"), r"expected '='"),
    (wrap(r"#1=A('\Q');"), r"backslash must start a control directive"),
    (wrap(r"#1=A('\X4\7FFFFFFF\X0\');"), r"above U\+10FFFF"),
    (wrap("#1=A(1);") + "#2=B();", r"after END-ISO-10303-21"),
    (wrap("#1=A(1);").replace("DATA;", "ANCHOR;"), r"ANCHOR sections"),
    (wrap("#1=A(1);").replace("DATA;", "DATUM;"), r"expected DATA or END-ISO-10303-21"),
    (wrap("#1=A(1);", header="FILE_SCHEMA(('X'))"), r"expected ';' after header entity FILE_SCHEMA"),
    (wrap("#1=A(1);", header="5;"), r"expected a header entity or ENDSEC"),
    (wrap("#1=A(1.5.5);"), r"expected ',' or '\)'"),
    (wrap("#1=A(1);").replace("DATA;", "/* no end DATA;"), r"unterminated comment"),
    (wrap("#1=A('ab'');"), r"unterminated string"),
])
def test_malformed_input_raises_step_error(text, match):
    with pytest.raises(StepError, match=match) as info:
        parse(text)
    assert info.value.line is not None


@pytest.mark.parametrize("tail", ["/*" * 100000, "#1=A(" + "'" * 100001, "#1=A(" + "(" * 100000])
def test_pathological_inputs_fail_in_linear_time(tail):
    """Unterminated comments and strings, deep nesting: an error, quickly (no quadratic rescans, no recursion)."""
    import time

    t0 = time.perf_counter()
    with pytest.raises(StepError):
        parse("ISO-10303-21;HEADER;ENDSEC;DATA;" + tail)
    assert time.perf_counter() - t0 < 5.0  # linear: ~0.1 s; a quadratic rescan would take minutes


def test_error_carries_entity_id_and_line():
    with pytest.raises(StepError, match=r"#7, line 7: .*expected ',' or '\)'") as info:
        parse(wrap("#6=A(1);\n#7=A(1 2);"))
    assert info.value.entity_id == 7 and info.value.line == 7


def test_dangling_reference_reported_at_resolution():
    f = parse(wrap("#1=A(#2,#3);\n#2=B();"))
    assert f.dangling() == [(1, 3)]
    with pytest.raises(StepError, match=r"#1, line 6: reference #3 points to no entity"):
        f.get(f.entities[1].params[1], f.entities[1])
    with pytest.raises(StepError, match=r"expected an entity reference #id, got 5"):
        f.get(5)


def test_unreadable_file_and_bad_input_type(tmp_path):
    with pytest.raises(StepError, match=r"cannot read"):
        parse_file(tmp_path / "missing.step")
    with pytest.raises(StepError, match=r"parse needs str or bytes, got int"):
        parse(5)


def test_latin1_bytes_and_bytes_input():
    f = parse(wrap("#1=A('caf\xe9');").encode("latin-1"))
    assert f.entities[1].params == ("café",)


# ---------------------------------------------------------------------------- fast path
def _general(text: str):
    from coons.io.step import p21

    toks, lines = p21._tokens(text)
    return p21._Parser(toks, lines).file()


def _same(a, b) -> None:
    assert a.header == b.header
    assert sorted(a.entities) == sorted(b.entities)
    for k, e in a.entities.items():
        g = b.entities[k]
        assert (e.name, e.params, e.parts, e.line) == (g.name, g.params, g.parts, g.line), k


MIXED = (
    "#1=CARTESIAN_POINT('',(0.,1.5,-2));\n"
    "#2 = DIRECTION ( 'NONE', ( 0.0, 1.5E-3, -2 ) ) ;\n"       # OCCT's spacing
    "#3=ADVANCED_FACE('',(#4,#5),#6,.T.);#4=EDGE_CURVE('',#1,#1,#7,.F.);\n"
    "#5=B_SPLINE_CURVE_WITH_KNOTS('',3,(#1,#2),.UNSPECIFIED.,.F.,.F.,(4,4),(0.,1.),.UNSPECIFIED.);\n"
    "#6=PRODUCT('it''s','a;b (c)','',(#3));\n"                # escapes and specials: general path
    "#7=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );\n"  # complex instance
    "#8=UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),#7,'d','e');\n"  # typed parameter
    "#9=B_SPLINE_SURFACE('',1,1,((#1,#1),(#1,#1)),.UNSPECIFIED.,.F.,.F.,.F.);\n"  # nested lists
    "#10=X('\\X2\\00E9\\X0\\',$,*,\"0FF\",());\n"
    "#11=Y((1.,2.),3,'a,b');#12=Z();\n"
    "#13=W('multi\nline',#1);\n"
    "#14=V(((#1),()),( (1.,2.) ),(#1,(2,3)),.T.);#15=U((((1))));\n"  # two levels deferred, three general
)


@pytest.mark.parametrize("text", [wrap(MIXED), wrap(MIXED.replace("\n", "\r\n")),
                                  wrap(MIXED) + "\n", wrap("/* a comment */" + MIXED)]
                         + [p.read_bytes().decode("latin-1") for p in CORPUS])
def test_fast_path_gives_the_general_parse(text):
    # Values, names, parts and line numbers equal the general tokenising parser's, entity by entity.
    _same(parse(text), _general(text))


def test_common_instances_are_deferred_until_used():
    from coons.io.step import p21

    f = parse(wrap(MIXED))
    assert f.entities[1]._raw is not None  # validated, not yet converted
    assert f.entities[1].params == ("", (0.0, 1.5, -2)) and f.entities[1]._raw is None
    assert f.entities[7]._raw is None and f.entities[6]._raw is None  # complex / escaped: parsed at once
    assert f.entities[9]._raw is not None and f.entities[14]._raw is not None  # lists two levels deep
    assert f.entities[15]._raw is None  # three levels: the general parser
    assert f.entities[14].params == (((Ref(1),), ()), ((1.0, 2.0),), (Ref(1), (2, 3)), True)
    assert p21._DEFERRABLE.fullmatch("'',(#1,#2),.T.,$,*,-1.5E+3")
    assert not p21._DEFERRABLE.fullmatch("'',1 2")  # tokens side by side
    assert not p21._DEFERRABLE.fullmatch("'a''b'")  # an escaped quote


@pytest.mark.parametrize("args, triple", [
    ("'',(0.,1.5,-2)", (0.0, 1.5, -2.0)),
    (" 'NONE' , ( 0.0 , 1.5E-3 ,\n -2 ) ", (0.0, 1.5e-3, -2.0)),
    ("'p',(1E999,0.,0.)", (float("inf"), 0.0, 0.0)),  # the reader checks finiteness itself
    ("'',(0.,1.5)", None),  # two coordinates
    ("'',(0.,1.5,-2,4.)", None),
    ("'',(#1,1.5,-2)", None),
    ("'',(0.,1.5,-2),#3", None),
    ("$,(0.,1.5,-2)", None),
])
def test_real_triple_is_the_params_of_a_plain_point(args, triple):
    f = parse(wrap(f"#1=CARTESIAN_POINT({args});\n"))
    e = f.entities[1]
    assert e.real_triple() == triple
    if triple is not None:
        assert tuple(map(float, e.params[1])) == triple  # params stay available and equal
        assert e.real_triple() is None  # read: nothing left to shortcut
    g = parse(wrap("#1=CARTESIAN_POINT('it''s',(0.,1.,2.));\n")).entities[1]  # escaped: general parser
    assert g.real_triple() is None and g.params == ("it's", (0.0, 1.0, 2.0))


@pytest.mark.parametrize("data, match, line", [
    ("#1=CARTESIAN_POINT('',(0.,1.5,-2));\n#2=CARTESIAN_POINT('',(0.,,1.));", "expected a parameter before ','", 7),
    ("#1=CARTESIAN_POINT('',(0.,1.5,-2));\n#2=DIRECTION('',(0. 1.));", "expected ',' or '\\)' after a parameter", 7),
    ("#1=CARTESIAN_POINT('',(0.,1.5,-2));\n#1=DIRECTION('',(0.,1.));", "duplicate entity id #1", 7),
    ("#1=CARTESIAN_POINT('',(0.,1_0,-2));", "expected ',' or", 6),
])
def test_errors_in_common_instances_keep_their_line(data, match, line):
    with pytest.raises(StepError, match=match) as info:
        parse(wrap(data))
    assert info.value.line == line


_TOKENS = st.sampled_from(["#12", "1.", "-2.5E-3", "+.5", "7", ".T.", ".UNSPECIFIED.", "$", "*", "''", "'a b'",
                           "'x;y'", "'it''s'", "(", ")", ",", " ", "\n", "1.2.3", "#", ".5.", "E5", "'"])


@given(st.lists(_TOKENS, max_size=14))
def test_fast_path_agrees_with_the_general_parser_on_any_arguments(tokens):
    # Valid or not, an instance's argument text gives the same values (or the same error) on both paths.
    text = wrap("#1=CARTESIAN_POINT('',(0.,0.,0.));\n#2=X(" + "".join(tokens) + ");\n#3=Y(#1);\n")
    try:
        expected = _general(text)
    except StepError as exc:
        with pytest.raises(StepError) as info:
            parse(text)
        assert (info.value.entity_id, info.value.line) == (exc.entity_id, exc.line)
        return
    _same(parse(text), expected)


_ATOMS = st.sampled_from(["#12", "1.", "-2.5E-3", "+.5", "7", "0.0", "1.E+07", ".T.", ".F.", ".UNSPECIFIED.", "$", "*",
                          "''", "'a b'", "'x;y'", "'it''s'"])
_WS = st.sampled_from(["", "", " ", "\n", " \r\n "])
_ARGS = st.recursive(_ATOMS, lambda inner: st.tuples(st.lists(st.tuples(_WS, inner, _WS), max_size=4)).map(
    lambda t: "(" + ",".join(a + x + b for a, x, b in t[0]) + ")"), max_leaves=12)


@given(st.lists(st.tuples(_WS, _ARGS, _WS), min_size=1, max_size=5))
def test_fast_path_agrees_with_the_general_parser_on_valid_arguments(args):
    # Well-formed arguments of every shape (nesting up to four levels, white space anywhere
    # between tokens): fast and general paths give the same values and lines.
    text = wrap("#1=CARTESIAN_POINT('',(0.,0.,0.));\n#2=X(" + ",".join(a + x + b for a, x, b in args) + ");\n#3=Y(#1);\n")
    _same(parse(text), _general(text))
