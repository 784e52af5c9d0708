"""Malformed TOML, CSV and option values thrown at the commands' parsers (property-based).

Whatever the input, a command either refuses it (exit 2, one line starting ``jaxclear: error:``,
no traceback, no output folder made) or accepts it and goes on to solve, which these tests stop at
its first ``simulate`` call: nothing is ever solved here.
"""

import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxclear
import jaxclear.cli._fit
from jaxclear import cli

EXAMPLES = 40
"""Examples per property: each is one in-process command, most refused while parsing."""
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,  # the same examples on every run: a failure is reproducible in CI
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
DATA = Path(__file__).parent / "reference" / "data" / "ident_5000rpm_B.csv"
FIT_CONFIG = Path(__file__).parents[1] / "examples" / "fit_clearance_B.toml"


class Solved(BaseException):  # not an Exception: the command line catches those
    """The input was accepted: the command got as far as solving."""


@pytest.fixture
def no_solve(monkeypatch):
    def stop(*args, **kwargs):
        raise Solved

    monkeypatch.setattr(jaxclear, "simulate", stop)  # what run solves through
    monkeypatch.setattr(jaxclear.cli._fit, "identify", stop)  # what fit solves through


def check(argv, out: Path, capsys):
    """Refused cleanly, or accepted up to the solve."""
    try:
        cli.main(argv)
    except Solved:
        return
    except SystemExit as exc:
        err = capsys.readouterr().err
        assert exc.code == 2, err
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("jaxclear: error: "), err
        assert "Traceback" not in err
        assert not out.exists() or not any(out.iterdir()), "a refused command wrote files"
        return
    raise AssertionError(f"{argv} neither refused nor solved")


SECTIONS = ["mechanism", "clearance", "simulation", "solver", "output", "clearance.B", "junk"]
KEYS = [
    "rpm",
    "clearance",
    "joints",
    "contact",
    "friction",
    "restitution",
    "revolutions",
    "method",
    "rtol",
    "max_steps",
    "gravity",
    "plots",
    "start",
    "name",
    "bogus",
]
VALUES = st.one_of(
    st.integers(-(10**12), 10**12).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda x: repr(x).replace("inf", "inf")),
    st.text(alphabet=string.ascii_letters + " -_.,", max_size=12).map(lambda s: f'"{s}"'),
    st.sampled_from(["true", "false", "[]", "[1, 2]", "{}", '"O,A,B"', '"none"', "nan", "-inf"]),
    st.text(max_size=8),  # not even TOML
)
TOML = st.lists(
    st.tuples(st.sampled_from(SECTIONS), st.sampled_from(KEYS), VALUES), max_size=4
).map(lambda items: "".join(f"[{s}]\n{k} = {v}\n" for s, k, v in items))


@FUZZ
@given(text=TOML)
def test_run_config_files(text, tmp_path_factory, capsys, no_solve):
    folder = tmp_path_factory.mktemp("toml")
    config = folder / "config.toml"
    config.write_text(text, encoding="utf-8")
    out = folder / "out"
    check(
        ["run", str(config), "--clearance-joints", "none", "--quiet", "--out", str(out)],
        out,
        capsys,
    )


OPTIONS = [
    "--rpm",
    "--clearance",
    "--restitution",
    "--revolutions",
    "--rtol",
    "--max-steps",
    "--clearance-joints",
    "--contact",
    "--friction",
    "--method",
    "--points-per-revolution",
]
OPTION_VALUES = st.one_of(
    st.sampled_from(["0", "-1", "1e9", "nan", "inf", "", " ", "1e-400", "1,2", "B,B", "0x10"]),
    st.text(alphabet=string.printable, max_size=10),
)


@FUZZ
@given(option=st.sampled_from(OPTIONS), value=OPTION_VALUES)
def test_run_option_values(option, value, tmp_path_factory, capsys, no_solve):
    folder = tmp_path_factory.mktemp("opt")
    out = folder / "out"
    check(["run", f"{option}={value}", "--quiet", "--out", str(out)], out, capsys)


def _mangle(text: str, cut: int, junk: str, where: int) -> str:
    cut = cut % (len(text) + 1)
    where = where % (cut + 1)
    return text[:where] + junk + text[where:cut]


HEAD = DATA.read_text(encoding="utf-8")[:4000]


@FUZZ
@given(
    cut=st.integers(0, len(HEAD)),
    junk=st.text(alphabet=string.printable + "µé", max_size=12),
    where=st.integers(0, len(HEAD)),
)
def test_fit_measurement_files(cut, junk, where, tmp_path_factory, capsys, no_solve):
    folder = tmp_path_factory.mktemp("csv")
    data = folder / "data.csv"
    data.write_text(_mangle(HEAD, cut, junk, where), encoding="utf-8")
    out = folder / "out"
    argv = ["fit", str(data), str(FIT_CONFIG), "--fit", "B.clearance", "--out", str(out)]
    check(argv, out, capsys)
