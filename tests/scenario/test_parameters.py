"""OpenSCENARIO parameters: expressions, declarations, constraints and variations."""

from __future__ import annotations

import ast
import math
import operator
import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from lxml import etree

from aldm_gym.errors import InputError, ScenarioError
from aldm_gym.scenario.declarations import (
    ParameterDeclaration,
    ValueConstraint,
    bind,
    declarations_from_xml,
    violations,
)
from aldm_gym.scenario.distributions import ConcreteRun, expand_variation, filter_runs
from aldm_gym.scenario.expressions import (
    ParamValue,
    evaluate,
    format_value,
    resolve,
    resolve_number,
)

ALKS_DIR = Path("/work/shared/osc-alks/logical_scenarios")
"""The ALKS logical scenarios (BMW's OpenSCENARIO ALKS examples)."""

needs_alks = pytest.mark.skipif(not ALKS_DIR.is_dir(), reason=f"{ALKS_DIR} does not exist")

CUT_IN = ALKS_DIR / "concrete_scenarios" / "alks_scenario_4_4_1_cut_in_no_collision_template.xosc"

# ---------------------------------------------------------------------------------------
# Expressions


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("${2 - 3 - 4}", -5),
        ("${16 / 4 / 2}", 2.0),
        ("${2 ** 3 ** 2}", 512.0),
        ("${-2 ** 2}", 4.0),
        ("${2 ** -1}", 0.5),
        ("${2 * 3 ** 2}", 18.0),
        ("${1 + 2 * 3}", 7),
        ("${(1 + 2) * 3}", 9),
        ("${-(1 + 2)}", -3),
        ("${- -2}", 2),
        ("${7 % 3}", 1),
        ("${-7 % 3}", -1),
        ("${7 % -3}", 1),
        ("${7.5 % 2}", 1.5),
        ("${1 + 2 == 3}", True),
        ("${1 != 1.0}", False),
        ("${2 >= 2 and 1 < 0.5}", False),
        ("${true or false and false}", True),
        ("${(true or false) and false}", False),
        ("${not true or true}", True),
        ("${not 1 < 2}", False),
        ("${not not true}", True),
        ("  ${ 1 +\t1 }  ", 2),
    ],
)
def test_precedence_and_associativity(text: str, expected: object) -> None:
    result = evaluate(text, {})
    assert result == expected
    assert type(result) is type(expected)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("${3}", 3),
        ("${3.0}", 3.0),
        ("${2.5e-1}", 0.25),
        ("${1E3}", 1000.0),
        ("${.5}", 0.5),
        ("${8 / 4}", 2.0),
        ("${2 * 1.5}", 3.0),
        ("${true}", True),
    ],
)
def test_literals_and_result_types(text: str, expected: object) -> None:
    result = evaluate(text, {})
    assert result == expected
    assert type(result) is type(expected)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("${round(2.5)}", 3),
        ("${round(-2.5)}", -3),
        ("${round(2.4)}", 2),
        ("${floor(-1.5)}", -2),
        ("${ceil(1.2)}", 2),
        ("${sqrt(16)}", 4.0),
        ("${pow(2, 10)}", 1024.0),
        ("${sin(0)}", 0.0),
        ("${cos(0)}", 1.0),
        ("${tan(0)}", 0.0),
        ("${asin(1) * 2}", math.pi),
        ("${acos(-1)}", math.pi),
        ("${atan(1) * 4}", math.pi),
        ("${sign(-3)}", -1),
        ("${sign(0)}", 0),
        ("${sign(2.5)}", 1.0),
        ("${abs(-3)}", 3),
        ("${abs(-2.5)}", 2.5),
        ("${max(1, 2)}", 2),
        ("${max(1, 2.5)}", 2.5),
        ("${min(-1, 2)}", -1),
        ("${min(sqrt(4), 3)}", 2.0),
        ("${2 * sqrt( $x * $x ) / ($v / 3.6)}", 2 * 5.0 / (18.0 / 3.6)),
    ],
)
def test_functions(text: str, expected: object) -> None:
    result = evaluate(text, {"x": -5.0, "v": 18.0})
    assert result == pytest.approx(expected)
    assert type(result) is type(expected)


def test_parameter_references() -> None:
    params: dict[str, ParamValue] = {"speed": 36.0, "lane": -1, "model": "car", "on": True}
    assert evaluate("${$speed / 3.6}", params) == 10.0
    assert evaluate("${$lane * -$speed}", params) == 36.0
    assert evaluate("${not $on}", params) is False
    assert evaluate("${$model}", params) == "car"
    assert resolve("$lane", params) == -1
    assert resolve(" $model ", params) == "car"
    assert resolve("${$lane + 1}", params) == 0
    assert resolve("car", params) == "car"
    assert resolve("./roads/a$b.xodr", params) == "./roads/a$b.xodr"
    assert resolve_number("$lane", params) == -1.0
    assert resolve_number("${$speed * 2}", params) == 72.0
    assert resolve_number(" 1.5e1 ", params) == 15.0


@pytest.mark.parametrize(
    ("text", "params", "parts"),
    [
        (
            "${$spede / 3.6}",
            {"speed": 1.0, "lane": 2},
            ["unknown parameter $spede", "did you mean $speed?", "$speed, $lane", "column 3"],
        ),
        ("${$a}", {}, ["unknown parameter $a", "no parameters are declared"]),
        ("${1 + * 2}", {}, ["column 7", "found '*'"]),
        ("${(1 + 2}", {}, ["column 9", "expected ')'"]),
        ("${1 2}", {}, ["column 5", "expected an operator"]),
        ("${1 + 2", {}, ["missing the closing '}'"]),
        ("${}", {}, ["empty expression"]),
        ("${1 # 2}", {}, ["column 5", "unexpected character '#'"]),
        ("${$ + 1}", {}, ["column 3", "'$' must start a parameter name"]),
        ("${1 < 2 < 3}", {}, ["column 9", "do not chain"]),
        ("${1 / 0}", {}, ["column 5", "division by zero"]),
        ("${1 / (2 - 2.0)}", {}, ["division by zero"]),
        ("${5 % 0}", {}, ["modulo by zero"]),
        ("${sqrt(-1)}", {}, ["column 3", "sqrt(-1) is undefined"]),
        ("${asin(2)}", {}, ["asin(2) is undefined"]),
        ("${acos(-1.5)}", {}, ["acos(-1.5) is undefined"]),
        ("${pow(-8, 1 / 3)}", {}, ["pow() is undefined for -8"]),
        ("${10 ** 400}", {}, ["overflows"]),
        ("${1e300 * 1e300}", {}, ["overflows"]),
        ("${foo(1)}", {}, ["unknown function 'foo'", "sqrt"]),
        ("${speed + 1}", {}, ["unknown function 'speed'", "parameters start with $"]),
        ("${max(1)}", {}, ["max() takes 2 arguments, got 1"]),
        ("${sqrt(1, 2)}", {}, ["sqrt() takes 1 argument, got 2"]),
        ("${true + 1}", {}, ["'+' needs numbers, got boolean 'true'"]),
        ("${not 1}", {}, ["'not' needs booleans, got integer '1'"]),
        ("${1 and true}", {}, ["'and' needs booleans"]),
        ("${$m * 2}", {"m": "car"}, ["'*' needs numbers, got string 'car'"]),
        ("${$m < 2}", {"m": "car"}, ["'<' compares numbers"]),
        ("${true == 1}", {}, ["'==' compares two numbers, booleans or strings"]),
    ],
)
def test_expression_errors_name_the_problem(
    text: str, params: dict[str, ParamValue], parts: list[str]
) -> None:
    where = "file.xosc:57 <AbsoluteTargetSpeed value>"
    with pytest.raises(InputError) as info:
        evaluate(text, params, where)
    message = str(info.value)
    assert message.startswith(f"{where}: {text!r}")
    for part in parts:
        assert part in message


def test_errors_without_where_start_with_the_text() -> None:
    with pytest.raises(InputError, match=r"^'\$\{1/0\}', column 4: division by zero$"):
        evaluate("${1/0}", {})


def test_and_or_short_circuit() -> None:
    assert evaluate("${false and 1 / 0 > 0}", {}) is False
    assert evaluate("${$v > 0 and 100 / $v < 5}", {"v": 0}) is False
    assert evaluate("${true or $missing}", {}) is True


@pytest.mark.parametrize(
    ("raw", "parts"),
    [
        ("$nope", ["unknown parameter $nope", "known parameters: $a"]),
        ("$5", ["neither a parameter reference"]),
        ("$a b", ["neither a parameter reference"]),
    ],
)
def test_resolve_errors(raw: str, parts: list[str]) -> None:
    with pytest.raises(InputError) as info:
        resolve(raw, {"a": 1}, "f.xosc:3 <X y>")
    assert str(info.value).startswith("f.xosc:3 <X y>: ")
    for part in parts:
        assert part in str(info.value)


@pytest.mark.parametrize(
    ("raw", "part"),
    [
        ("car", "expected a number, got string 'car'"),
        ("NaN", "expected a number, got string 'NaN'"),
        ("INF", "expected a number, got string 'INF'"),
        ("1e999", "expected a number, got inf"),
        ("true", "expected a number, got string 'true'"),
        ("$flag", "expected a number, got boolean 'true'"),
        ("${1 > 0}", "expected a number, got boolean 'true'"),
        ("", "expected a number, got string ''"),
    ],
)
def test_resolve_number_rejects_non_numbers(raw: str, part: str) -> None:
    with pytest.raises(InputError) as info:
        resolve_number(raw, {"flag": True}, "f.xosc:9 <Range lowerLimit>")
    assert str(info.value).startswith("f.xosc:9 <Range lowerLimit>: ")
    assert part in str(info.value)


def test_format_value() -> None:
    assert [format_value(v) for v in (True, False, 3, 2.5, -0.0, "x")] == [
        "true",
        "false",
        "3",
        "2.5",
        "0.0",
        "x",
    ]


def _tree(depth: int) -> st.SearchStrategy[str]:
    leaf = st.integers(-50, 50).map(lambda n: f"({n})" if n < 0 else str(n))
    if depth == 0:
        return leaf
    sub = _tree(depth - 1)
    return st.one_of(
        leaf,
        st.tuples(sub, st.sampled_from(["+", "-", "*"]), sub).map(
            lambda t: f"{t[0]} {t[1]} {t[2]}"
        ),
        sub.map(lambda s: f"({s})"),
        sub.map(lambda s: f"-({s})"),
    )


@given(_tree(4))
def test_integer_arithmetic_matches_python(expr: str) -> None:
    # + - * and unary minus on ints: the same precedence and results as Python
    # (Python's ** and unary minus differ, so the trees hold neither).
    result = evaluate("${" + expr + "}", {})
    assert type(result) is int
    assert result == _python_int(expr)


def _python_int(expr: str) -> int:
    # A reference without eval: Python's own parser, and int arithmetic on its tree.
    ops = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul}

    def walk(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return -walk(node.operand)
        assert isinstance(node, ast.BinOp)
        return ops[type(node.op)](walk(node.left), walk(node.right))

    return walk(ast.parse(expr, mode="eval").body)


@given(st.floats(min_value=0, max_value=1e300, allow_nan=False, allow_infinity=False))
def test_float_literals_round_trip(x: float) -> None:
    assert evaluate("${" + repr(x) + "}", {}) == x
    assert resolve_number(format_value(x), {}) == x


# ---------------------------------------------------------------------------------------
# Declarations, binding and constraints


def _declarations(xml: str) -> list[ParameterDeclaration]:
    return declarations_from_xml(etree.fromstring(xml))


def test_declarations_from_xml_reads_types_groups_and_lines() -> None:
    decls = _declarations(
        """<ParameterDeclarations>
  <!-- a comment -->
  <ParameterDeclaration name="a" parameterType="double" value="2.0"/>
  <ParameterDeclaration name="b" parameterType="integer" value="${$a * 3}">
    <ConstraintGroup>
      <ValueConstraint rule="greaterThan" value="0"/>
      <ValueConstraint rule="lessThan" value="$a"/>
    </ConstraintGroup>
    <ConstraintGroup><ValueConstraint rule="equalTo" value="6"/></ConstraintGroup>
  </ParameterDeclaration>
</ParameterDeclarations>"""
    )
    assert decls == [
        ParameterDeclaration("a", "double", "2.0", (), 3),
        ParameterDeclaration(
            "b",
            "integer",
            "${$a * 3}",
            (
                (ValueConstraint("greaterThan", "0", 6), ValueConstraint("lessThan", "$a", 7)),
                (ValueConstraint("equalTo", "6", 9),),
            ),
            4,
        ),
    ]
    assert declarations_from_xml(None) == []
    assert bind(decls, {}, "f.xosc") == {"a": 2.0, "b": 6}


@pytest.mark.parametrize(
    ("xml", "parts"),
    [
        (
            '<ParameterDeclaration name="a" parameterType="double"/>',
            [":2 <ParameterDeclaration>", "'value'"],
        ),
        ('<ParameterDeclaration name="a" parameterType="float" value="1"/>', ["'float'"]),
        ('<ParameterDeclaration name="a b" parameterType="double" value="1"/>', ["'a b'"]),
        ('<Parameter name="a" parameterType="double" value="1"/>', ["<Parameter>", "unknown"]),
        (
            '<ParameterDeclaration name="a" parameterType="double" value="1">'
            '<ConstraintGroup><ValueConstraint rule="atMost" value="1"/></ConstraintGroup>'
            "</ParameterDeclaration>",
            ["<ValueConstraint>", "'atMost'"],
        ),
        (
            '<ParameterDeclaration name="a" parameterType="double" value="1">'
            "<ConstraintGroup/></ParameterDeclaration>",
            ["<ConstraintGroup>", "at least one ValueConstraint"],
        ),
    ],
)
def test_declaration_errors_name_element_and_line(xml: str, parts: list[str]) -> None:
    with pytest.raises(InputError) as info:
        _declarations(f"<ParameterDeclarations>\n{xml}\n</ParameterDeclarations>")
    for part in parts:
        assert part in str(info.value)


def test_bind_types_and_overrides() -> None:
    decls = [
        ParameterDeclaration("v", "double", "60", line=1),
        ParameterDeclaration("n", "integer", "-1", line=2),
        ParameterDeclaration("u", "unsignedShort", "${round($v / 7)}", line=3),
        ParameterDeclaration("flag", "boolean", "true", line=4),
        ParameterDeclaration("name", "string", "$v", line=5),
        ParameterDeclaration("when", "dateTime", "2021-07-06T10:00:00", line=6),
    ]
    assert bind(decls, {}, "f.xosc") == {
        "v": 60.0,
        "n": -1,
        "u": 9,
        "flag": True,
        "name": "60.0",
        "when": "2021-07-06T10:00:00",
    }
    values = bind(decls, {"v": "14.0", "n": "5.0", "flag": False, "name": "car"}, "f.xosc")
    assert values["v"] == 14.0 and values["u"] == 2
    assert values["n"] == 5 and type(values["n"]) is int
    assert values["flag"] is False and values["name"] == "car"
    assert bind(decls, {"v": 7, "flag": "0"}, "f.xosc")["flag"] is False


@pytest.mark.parametrize(
    ("overrides", "parts"),
    [
        ({"speed": "1"}, ["f.xosc: cannot override undeclared parameter speed", "declares: v, n"]),
        ({"nn": "1"}, ["undeclared parameter nn (did you mean n?)"]),
        ({"n": "1.5"}, ["override n", "parameter n is of type integer: '1.5' is not an integer"]),
        ({"n": "3000000000"}, ["parameter n is of type integer", "not in [-2147483648"]),
        ({"v": "fast"}, ["parameter v is of type double: 'fast' is not a number"]),
        ({"v": True}, ["parameter v is of type double: 'true' is not a number"]),
        ({"flag": "yes"}, ["parameter flag is of type boolean: 'yes' is not a boolean"]),
        ({"n": "$flag"}, ["unknown parameter $flag", "known parameters: $v"]),
        ({"v": "${1/0}"}, ["f.xosc: override v: '${1/0}', column 4: division by zero"]),
    ],
)
def test_bind_errors_name_parameter_and_type(
    overrides: dict[str, object], parts: list[str]
) -> None:
    decls = [
        ParameterDeclaration("v", "double", "60", line=1),
        ParameterDeclaration("n", "integer", "-1", line=2),
        ParameterDeclaration("flag", "boolean", "true", line=3),
    ]
    with pytest.raises(InputError) as info:
        bind(decls, overrides, "f.xosc")
    for part in parts:
        assert part in str(info.value)


def test_bind_rejects_forward_references_and_duplicates() -> None:
    forward = [
        ParameterDeclaration("a", "double", "${$b + 1}", line=7),
        ParameterDeclaration("b", "double", "1", line=8),
    ]
    with pytest.raises(InputError, match=r"^f\.xosc:7 <ParameterDeclaration a value>: .*\$b"):
        bind(forward, {}, "f.xosc")
    twice = [ParameterDeclaration("a", "double", "1", line=1)] * 2
    with pytest.raises(InputError, match="declared twice"):
        bind(twice, {}, "f.xosc")


def test_string_constraints_compare_as_strings() -> None:
    decls = [
        ParameterDeclaration(
            "lane",
            "string",
            "-4",
            ((ValueConstraint("equalTo", "-4"),), (ValueConstraint("equalTo", "4"),)),
            10,
        )
    ]
    assert violations(decls, bind(decls, {"lane": "4"}, "f.xosc"), "f.xosc") == []
    [reason] = violations(decls, bind(decls, {"lane": "-4.0"}, "f.xosc"), "f.xosc")
    assert reason == (
        "lane = -4.0 (f.xosc:10) meets none of its constraint groups: [equalTo -4] or [equalTo 4]"
    )
    ordered = [
        ParameterDeclaration("m", "string", "car", ((ValueConstraint("lessThan", "z", 3),),))
    ]
    with pytest.raises(
        InputError, match=r"^f\.xosc:3 <ValueConstraint value>: rule lessThan .* string"
    ):
        violations(ordered, {"m": "car"}, "f.xosc")


@pytest.fixture(scope="module")
def cut_in() -> list[ParameterDeclaration]:
    root = etree.parse(str(CUT_IN)).getroot()
    return declarations_from_xml(root.find("ParameterDeclarations"))


@needs_alks
def test_cut_in_template_declarations(cut_in: list[ParameterDeclaration]) -> None:
    assert [d.name for d in cut_in] == [
        "Ego_InitSpeed_Ve0_kph",
        "CutInVehicle_Model",
        "CutInVehicle_InitPosition_RelativeLaneId",
        "CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph",
        "CutInVehicle_HeadwayDistanceTrigger_dx0_m",
        "CutInVehicle_LaneChange_MaxLateralVelocity_Vy_mps",
        "CutInVehicle_Acceleration_Rate_mps2",
        "CutInVehicle_Acceleration_Target_kph",
    ]
    relative = cut_in[3]
    assert relative.line == 27
    assert relative.constraint_groups == (
        (ValueConstraint("lessThan", "0.0", 29),),
        (ValueConstraint("greaterThan", "${-$Ego_InitSpeed_Ve0_kph}", 32),),
    )
    values = bind(cut_in, {}, str(CUT_IN))
    assert values["CutInVehicle_InitPosition_RelativeLaneId"] == -1
    assert violations(cut_in, values, str(CUT_IN)) == []


@needs_alks
@pytest.mark.parametrize(
    ("overrides", "failing"),
    [
        # AND within a group: > 0 holds, <= 60 does not.
        ({"Ego_InitSpeed_Ve0_kph": "70"}, ["Ego_InitSpeed_Ve0_kph = 70.0"]),
        # ... and at 0 the lateral velocity's bound (0 - 20) / 3.6 fails too.
        ({"Ego_InitSpeed_Ve0_kph": "0"}, ["Ego_InitSpeed_Ve0_kph = 0.0", "Vy_mps = 2.0"]),
        ({"Ego_InitSpeed_Ve0_kph": "60"}, []),
        # OR across groups: equalTo -1 or equalTo 1.
        ({"CutInVehicle_InitPosition_RelativeLaneId": "1"}, []),
        ({"CutInVehicle_InitPosition_RelativeLaneId": "2"}, ["RelativeLaneId = 2"]),
        # OR: "lessThan 0" alone suffices although -70 < -$Ego (60).
        ({"CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph": "-70"}, ["Vy_mps = 2.0"]),
        # ... and "greaterThan ${-$Ego}" alone suffices for a positive value.
        ({"CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph": "10"}, []),
        # The lateral velocity's bound is an expression over two other parameters.
        (
            {
                "Ego_InitSpeed_Ve0_kph": "20",
                "CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph": "-50",
                "CutInVehicle_LaneChange_MaxLateralVelocity_Vy_mps": "0.5",
            },
            ["Vy_mps = 0.5"],
        ),
        ({"CutInVehicle_Acceleration_Target_kph": "-5"}, []),
    ],
)
def test_cut_in_constraint_groups(
    cut_in: list[ParameterDeclaration], overrides: dict[str, str], failing: list[str]
) -> None:
    found = violations(cut_in, bind(cut_in, overrides, str(CUT_IN)), str(CUT_IN))
    assert len(found) == len(failing)
    for reason, part in zip(found, failing, strict=True):
        assert part in reason


@needs_alks
def test_cut_in_violation_reads_well(cut_in: list[ParameterDeclaration]) -> None:
    overrides = {
        "Ego_InitSpeed_Ve0_kph": "20",
        "CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph": "-50",
        "CutInVehicle_LaneChange_MaxLateralVelocity_Vy_mps": "0.5",
    }
    [reason] = violations(cut_in, bind(cut_in, overrides, "cut_in.xosc"), "cut_in.xosc")
    assert reason == (
        "CutInVehicle_LaneChange_MaxLateralVelocity_Vy_mps = 0.5 (cut_in.xosc:40) meets none "
        "of its constraint groups: [greaterThan 0.0 and lessThan "
        "${($Ego_InitSpeed_Ve0_kph + $CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph) / 3.6}"
        " = -8.333333333333334]"
    )


# ---------------------------------------------------------------------------------------
# Parameter variation


def _variation(tmp_path: Path, body: str, header: str = "") -> Path:
    path = tmp_path / "v.xosc"
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n<OpenSCENARIO>\n'
        '<FileHeader revMajor="1" revMinor="2" date="2024-01-01T00:00:00"/>\n'
        f"{header}<ParameterValueDistribution>\n"
        '<ScenarioFile filepath="./scenarios/s.xosc"/>\n'
        f"{body}\n</ParameterValueDistribution>\n</OpenSCENARIO>\n"
    )
    return path


def _values(runs: list[ConcreteRun]) -> list[dict[str, str]]:
    assert [r.index for r in runs] == list(range(len(runs)))
    return [r.parameters for r in runs]


def test_deterministic_cross_product_last_varies_fastest(tmp_path: Path) -> None:
    path = _variation(
        tmp_path,
        """<Deterministic>
  <DeterministicSingleParameterDistribution parameterName="a">
    <DistributionSet><Element value="x"/><Element value="y"/></DistributionSet>
  </DeterministicSingleParameterDistribution>
  <DeterministicMultiParameterDistribution><ValueSetDistribution>
    <ParameterValueSet>
      <ParameterAssignment parameterRef="b" value="1"/>
      <ParameterAssignment parameterRef="c" value="p"/>
    </ParameterValueSet>
    <ParameterValueSet><ParameterAssignment parameterRef="b" value="2"/></ParameterValueSet>
  </ValueSetDistribution></DeterministicMultiParameterDistribution>
  <DeterministicSingleParameterDistribution parameterName="d">
    <DistributionRange stepWidth="0.5"><Range lowerLimit="-0.5" upperLimit="0"/></DistributionRange>
  </DeterministicSingleParameterDistribution>
</Deterministic>""",
    )
    scenario, runs = expand_variation(path)
    assert scenario == tmp_path / "scenarios" / "s.xosc"
    assert _values(runs) == [
        {"a": "x", "b": "1", "c": "p", "d": "-0.5"},
        {"a": "x", "b": "1", "c": "p", "d": "0.0"},
        {"a": "x", "b": "2", "d": "-0.5"},
        {"a": "x", "b": "2", "d": "0.0"},
        {"a": "y", "b": "1", "c": "p", "d": "-0.5"},
        {"a": "y", "b": "1", "c": "p", "d": "0.0"},
        {"a": "y", "b": "2", "d": "-0.5"},
        {"a": "y", "b": "2", "d": "0.0"},
    ]


@pytest.mark.parametrize(
    ("step", "lower", "upper", "expected"),
    [
        ("0.1", "0", "0.3", ["0.0", "0.1", "0.2", "0.3"]),
        ("0.3", "0", "1", ["0.0", "0.3", "0.6", "0.9"]),
        ("1.5", "-3.0", "3.0", ["-3.0", "-1.5", "0.0", "1.5", "3.0"]),
        ("5", "7", "7", ["7.0"]),
        ("10", "1", "5", ["1.0"]),
        ("0.7", "0.1", "2.2", ["0.1", "0.8", "1.5", "2.2"]),
        ("${1 / 3}", "0", "1", ["0.0", "0.333333333333", "0.666666666667", "1.0"]),
    ],
)
def test_distribution_range_is_robust_to_float_drift(
    tmp_path: Path, step: str, lower: str, upper: str, expected: list[str]
) -> None:
    path = _variation(
        tmp_path,
        f"<Deterministic>{_single(_range(step, lower, upper), 'x')}</Deterministic>",
    )
    assert [run.parameters["x"] for run in expand_variation(path)[1]] == expected


@given(
    lower=st.integers(-1000, 1000),
    step=st.sampled_from([0.01, 0.05, 0.1, 0.25, 0.3, 0.7, 1.1, 2.5]),
    count=st.integers(0, 60),
)
def test_range_includes_an_upper_limit_on_the_grid(lower: int, step: float, count: int) -> None:
    # The upper limit carries the float drift of lower + count * step, as a file would.
    lo = lower / 10
    hi = float(f"{lo + count * step:.10g}")
    body = f"<Deterministic>{_single(_range(repr(step), repr(lo), repr(hi)), 'x')}</Deterministic>"
    with tempfile.TemporaryDirectory() as folder:
        runs = expand_variation(_variation(Path(folder), body))[1]
    values = [float(run.parameters["x"]) for run in runs]
    assert len(values) == count + 1
    assert values[0] == lo
    assert values[-1] == pytest.approx(hi, abs=1e-9)


def _single(inner: str, name: str = "a") -> str:
    return (
        f'<DeterministicSingleParameterDistribution parameterName="{name}">{inner}'
        "</DeterministicSingleParameterDistribution>"
    )


def _range(step: str, lower: str, upper: str) -> str:
    return (
        f'<DistributionRange stepWidth="{step}">'
        f'<Range lowerLimit="{lower}" upperLimit="{upper}"/></DistributionRange>'
    )


def _stochastic(inner: str, attributes: str = 'numberOfTestRuns="2"') -> str:
    return (
        f'<Stochastic {attributes}><StochasticDistribution parameterName="a">{inner}'
        "</StochasticDistribution></Stochastic>"
    )


@pytest.mark.parametrize(
    ("body", "parts"),
    [
        (
            "<Deterministic><Bogus/></Deterministic>",
            ["v.xosc:6 <Bogus>", "unknown element"],
        ),
        (
            '<Deterministic/><Stochastic numberOfTestRuns="1"/>',
            ["either <Deterministic> or <Stochastic>"],
        ),
        (
            "<Deterministic><ParameterValueSet/></Deterministic>",
            [":6 <ParameterValueSet>", "DeterministicMultiParameterDistribution"],
        ),
        (
            f"<Deterministic>{_single(_range('0', '0', '1'))}</Deterministic>",
            ["<DistributionRange>", "stepWidth must be > 0"],
        ),
        (
            f"<Deterministic>{_single(_range('1', '2', '1'))}</Deterministic>",
            ["<Range>", "below lowerLimit"],
        ),
        (
            f"<Deterministic>{_single(_range('1', '0', '1'))}"
            f"{_single(_range('1', '5', '6'))}</Deterministic>",
            ["parameter a is already varied by the distribution at line 6"],
        ),
        (
            f"<Deterministic>{_single('<DistributionSet/>')}</Deterministic>",
            ["<DistributionSet>", "needs at least one <Element>"],
        ),
        (
            "<Deterministic>"
            + _single('<DistributionSet><Element valu="1"/></DistributionSet>')
            + "</Deterministic>",
            ["<Element>", "missing attribute 'value'"],
        ),
        (
            _stochastic('<LogNormalDistribution expectedValue="1" variance="1"/>'),
            ["<LogNormalDistribution>", "not supported"],
        ),
        (
            _stochastic(
                '<UniformDistribution><Range lowerLimit="0" upperLimit="1"/></UniformDistribution>',
                'numberOfTestRuns="2" randomSeed="1.5"',
            ),
            ["<Stochastic>", "randomSeed must be a whole number"],
        ),
        (
            _stochastic(
                '<NormalDistribution expectedValue="0" variance="1">'
                '<Range lowerLimit="50" upperLimit="51"/></NormalDistribution>'
            ),
            [":6 <NormalDistribution>", "draws fell outside the Range [50.0, 51.0]"],
        ),
    ],
)
def test_variation_errors_name_file_element_and_line(
    tmp_path: Path, body: str, parts: list[str]
) -> None:
    path = _variation(tmp_path, body)
    with pytest.raises(InputError) as info:
        expand_variation(path)
    assert str(info.value).startswith(f"{path.name}:")
    for part in parts:
        assert part in str(info.value)


def test_variation_file_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        expand_variation(tmp_path / "missing.xosc")
    broken = tmp_path / "broken.xosc"
    broken.write_text("<OpenSCENARIO>\n<FileHeader>\n</OpenSCENARIO>")
    with pytest.raises(InputError, match=r"broken\.xosc:3: malformed XML"):
        expand_variation(broken)
    scenario = tmp_path / "scenario.xosc"
    scenario.write_text("<OpenSCENARIO><FileHeader/><ParameterDeclarations/></OpenSCENARIO>")
    with pytest.raises(InputError, match=":1 <ParameterDeclarations>: unknown element"):
        expand_variation(scenario)


STOCHASTIC = """<Stochastic numberOfTestRuns="200" randomSeed="{seed}">
  <StochasticDistribution parameterName="u">
    <UniformDistribution><Range lowerLimit="-1" upperLimit="2"/></UniformDistribution>
  </StochasticDistribution>
  <StochasticDistribution parameterName="n">
    <NormalDistribution expectedValue="10" variance="4">
      <Range lowerLimit="9" upperLimit="12"/>
    </NormalDistribution>
  </StochasticDistribution>
  <StochasticDistribution parameterName="p">
    <PoissonDistribution expectedValue="3"/>
  </StochasticDistribution>
  <StochasticDistribution parameterName="h">
    <Histogram>
      <Bin weight="1"><Range lowerLimit="0" upperLimit="1"/></Bin>
      <Bin weight="3"><Range lowerLimit="5" upperLimit="6"/></Bin>
    </Histogram>
  </StochasticDistribution>
  <StochasticDistribution parameterName="m">
    <ProbabilityDistributionSet>
      <Element value="car" weight="0.5"/>
      <Element value="truck" weight="1.5"/>
      <Element value="bus" weight="0"/>
    </ProbabilityDistributionSet>
  </StochasticDistribution>
</Stochastic>"""


def test_stochastic_runs_are_seeded_and_within_their_ranges(tmp_path: Path) -> None:
    first = _values(expand_variation(_variation(tmp_path, STOCHASTIC.format(seed=7)))[1])
    again = _values(expand_variation(_variation(tmp_path, STOCHASTIC.format(seed=7)))[1])
    other = _values(expand_variation(_variation(tmp_path, STOCHASTIC.format(seed=8)))[1])
    assert len(first) == 200
    assert first == again
    assert first != other
    u = [float(r["u"]) for r in first]
    n = [float(r["n"]) for r in first]
    p = [r["p"] for r in first]
    h = [float(r["h"]) for r in first]
    m = [r["m"] for r in first]
    assert all(-1 <= x <= 2 for x in u)
    assert all(9 <= x <= 12 for x in n)
    assert all(x.isdigit() for x in p)
    assert 2 < sum(int(x) for x in p) / len(p) < 4
    assert all(0 <= x <= 1 or 5 <= x <= 6 for x in h)
    assert 0.6 < sum(x >= 5 for x in h) / len(h) < 0.9
    assert set(m) == {"car", "truck"}
    assert list(first[0]) == ["u", "n", "p", "h", "m"]


def test_filter_runs_keeps_runs_within_constraints(tmp_path: Path) -> None:
    decls = [
        ParameterDeclaration("v", "double", "10", ((ValueConstraint("greaterThan", "0"),),), 1),
        ParameterDeclaration("w", "double", "1", ((ValueConstraint("lessThan", "$v"),),), 2),
    ]
    runs = [ConcreteRun(i, {"v": v, "w": "5"}) for i, v in enumerate(["10", "3", "-1"])]
    kept, dropped = filter_runs(runs, decls, "s.xosc")
    assert kept == [runs[0]]
    assert [(run.index, len(reasons)) for run, reasons in dropped] == [(1, 1), (2, 2)]
    assert dropped[1][1][0].startswith("v = -1.0 (s.xosc:1) meets none")
    with pytest.raises(InputError, match=r"^run 0 \(x=1\): s\.xosc: cannot override undeclared"):
        filter_runs([ConcreteRun(0, {"x": "1"})], decls, "s.xosc")


ALKS_RUNS = {
    "alks_scenario_4_1_1_free_driving_variation.xosc": (12, 12),
    "alks_scenario_4_1_2_swerving_lead_vehicle_variation.xosc": (300, 300),
    "alks_scenario_4_1_3_side_vehicle_variation.xosc": (1200, 1200),
    "alks_scenario_4_2_1_fully_blocking_target_variation.xosc": (360, 360),
    "alks_scenario_4_2_2_partially_blocking_target_variation.xosc": (6120, 6120),
    "alks_scenario_4_2_3_crossing_pedestrian_variation.xosc": (120, 120),
    "alks_scenario_4_2_4_multiple_blocking_targets_variation.xosc": (1800, 1800),
    # LeadVehicle_Init_LateralOffset_m: the range starts at -1.75, the constraint is > -1.75.
    "alks_scenario_4_3_1_follow_lead_vehicle_comfortable_variation.xosc": (2400, 2100),
    "alks_scenario_4_3_2_follow_lead_vehicle_emergency_brake_variation.xosc": (1400, 1225),
    # LeadVehicle_Deceleration_Rate_mps2: the range ends at 10, the constraint is < 10.
    "alks_scenario_4_3_2_follow_lead_vehicle_emergency_brake_variation_reference.xosc": (
        3000,
        2700,
    ),
    # Lateral velocity < (ego + relative speed) / 3.6: 85 of the 150 (ego, relative,
    # lateral) triples, times 5 models x 2 lanes x 7 headways x 5 accelerations.
    "alks_scenario_4_4_1_cut_in_no_collision_variation.xosc": (52500, 29750),
    # Lateral velocity < ego / 3.6: 67 of the 72 (ego, lateral) pairs.
    "alks_scenario_4_5_1_cut_out_fully_blocking_variation.xosc": (8640, 8040),
    "alks_scenario_4_5_2_cut_out_multiple_blocking_targets_variation.xosc": (43200, 40200),
    "alks_scenario_4_6_1_forward_detection_range_variation.xosc": (6, 6),
    "alks_scenario_4_6_2_lateral_detection_range_variation.xosc": (2, 2),
}
"""Runs before and after constraint filtering per ALKS variation file."""


@needs_alks
def test_every_alks_variation_file_is_listed() -> None:
    assert sorted(p.name for p in ALKS_DIR.glob("*_variation*.xosc")) == sorted(ALKS_RUNS)


@needs_alks
@pytest.mark.parametrize("name", sorted(ALKS_RUNS))
def test_alks_variations_expand_and_filter(name: str) -> None:
    scenario, runs = expand_variation(ALKS_DIR / name)
    assert scenario.is_file()
    root = etree.parse(str(scenario)).getroot()
    decls = declarations_from_xml(root.find("ParameterDeclarations"))
    kept, dropped = filter_runs(runs, decls, str(scenario))
    assert (len(runs), len(kept)) == ALKS_RUNS[name]
    assert len(kept) + len(dropped) == len(runs)
    assert all(reasons for _, reasons in dropped)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("${" + "(" * 120 + "1" + ")" * 120 + "}", "nested deeper than 64 levels"),
        ("${" + "-" * 100 + "1}", "nested deeper than 64 levels"),
        ("${" + "+".join(["1"] * 300) + "}", r"599 tokens, more than the 256 allowed"),
        ("${" + "1+" * 1500 + "1}", r"an expression of \d+ characters \(at most 2000\)"),
        ("${99999999999999999999}", "is out of range"),
        ("${" + "9" * 50 + ".0}", "a number of 52 characters"),
        ("${10**400}", "overflows"),
        ("${pow(10, 400)}", "overflows"),
    ],
)
def test_an_expression_too_large_or_deep_is_refused_by_name(text: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        evaluate(text, {})
