"""The add-on's table of settings (addon/penumbra/settings_table.py) against the solver's (PENUMBRA_SETTINGS in
native/src/solve/settings.h, exported as _native.SETTINGS), and the CLI's flags against both: every solver
setting has an entry with the same type, default and range, the solver refuses just outside each bound in the
table's words, and the CLI accepts exactly what the solver accepts. The Blender properties built from the
table are checked in blender_tests/test_settings_table.py."""
import importlib.util
import math
import os
import re

import pytest

import _native
import corpus
import settings_table as table

TYPES = {float: "float", int: "int", bool: "bool"}


def _cli():
    """cli.py loaded as Blender's --python loads it: a script beside the table, not a package module."""
    here = os.path.dirname(os.path.abspath(table.__file__))
    spec = importlib.util.spec_from_file_location("penumbra_cli_under_test", os.path.join(here, "cli.py"))
    cli = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cli)
    return cli


def _outside(s):
    """Values just outside each bound of s's range (none past an unbounded closed end)."""
    lo, a, b, hi = s.range
    step = (lambda x, d: x + d) if s.type is int else (lambda x, d: math.nextafter(x, d * math.inf))
    out = [a if lo == "(" else step(a, -1)]
    if b != math.inf:
        out.append(b if hi == ")" else step(b, +1))
    elif hi == ")":
        out.append(math.inf)              # finite only
    return out


def _inside(s):
    lo, a, b, hi = s.range
    step = (lambda x, d: x + d) if s.type is int else (lambda x, d: math.nextafter(x, d * math.inf))
    ins = [a if lo == "[" else step(a, +1)]
    if b != math.inf:
        ins.append(b if hi == "]" else step(b, -1))
    return ins


def test_the_tables_hold_the_same_settings_in_the_same_order():
    assert [e["name"] for e in _native.SETTINGS] == [s.name for s in table.SETTINGS]


@pytest.mark.parametrize("native", _native.SETTINGS, ids=lambda e: e["name"])
def test_each_setting_has_the_solvers_type_default_and_range(native):
    s = table.BY_NAME[native["name"]]
    assert TYPES[s.type] == native["type"]
    assert type(s.default) is s.type and s.default == native["default"]
    assert s.range == native["range"]
    if s.type is not bool:
        assert s.contains(s.default)


@pytest.mark.parametrize("s", [s for s in table.SETTINGS if s.type is not bool], ids=lambda s: s.name)
def test_the_solver_refuses_just_outside_each_bound_in_the_tables_words(s):
    args = corpus.room().arrays()
    for value in _outside(s):
        assert not s.contains(value)
        with pytest.raises(ValueError, match=re.escape(s.name)) as e:
            _native.solve(*args, settings={s.name: value})
        assert s.describe() in str(e.value), (value, str(e.value))


def test_bool_settings_take_only_true_or_false():
    for s in table.SETTINGS:
        if s.type is bool:
            with pytest.raises(ValueError, match=f"'{s.name}' must be True or False"):
                _native.solve(*corpus.room().arrays(), settings={s.name: 1})


def test_an_unknown_setting_is_refused():
    with pytest.raises(ValueError, match="unknown setting 'final_gathering'"):
        _native.solve(*corpus.room().arrays(), settings={"final_gathering": True})


def test_the_panel_stays_inside_the_solvers_ranges():
    """The properties' hard limits (settings_table.panel_limits) and the presets are values the solver takes,
    so nothing set in the panel is refused after the export."""
    for s in table.PANEL:
        assert s.group in {g for g, _, _ in table.PANEL_GROUPS}
        if s.type is bool:
            continue
        lo, hi = table.panel_limits(s)
        assert s.contains(lo) and s.contains(hi), s.name
        assert lo <= table.panel_default(s) <= hi, s.name
    for preset in table.PRESETS.values():
        for name, value in preset.items():
            assert table.BY_NAME[name].panel and table.BY_NAME[name].contains(value)
    for _, _, switch in table.PANEL_GROUPS:
        assert switch is None or table.BY_NAME[switch].type is bool


def test_the_cli_has_one_flag_per_panel_setting_with_the_solvers_range():
    cli = _cli()
    ap = cli.parser()
    flags = {a.dest: a for a in ap._actions}
    for s in table.SETTINGS:
        assert (s.name in flags) == s.panel, s.name
    base = ["--out", "o"]
    for s in table.PANEL:
        if s.type is bool:
            assert ap.parse_args(base + [s.flag]).__dict__[s.name] is True
            assert ap.parse_args(base + ["--no-" + s.flag[2:]]).__dict__[s.name] is False
            assert ap.parse_args(base).__dict__[s.name] is None      # the file's setting stays
            continue
        for value in _inside(s):
            assert ap.parse_args(base + [s.flag, repr(value)]).__dict__[s.name] == value
        for value in _outside(s):
            with pytest.raises(SystemExit) as e:
                ap.parse_args(base + [s.flag, repr(value)])
            assert e.value.code == 2, (s.name, value)


def test_cli_visibility_rays_stops_where_the_solver_does(capsys):
    """It accepted up to 1024 while the solver refuses more than 256 (then exit 3 after loading the scene)."""
    ap = _cli().parser()
    assert ap.parse_args(["--out", "o", "--visibility-rays", "256"]).visibility_rays == 256
    with pytest.raises(SystemExit) as e:
        ap.parse_args(["--out", "o", "--visibility-rays", "257"])
    assert e.value.code == 2
    assert "--visibility-rays: must be in [1, 256], got 257" in capsys.readouterr().err



def test_help_texts_survive_argparse():
    """The CLI hands each help text to argparse, which formats it with %: a bare % (as in "18 % less") makes
    `--help` and every CLI error raise TypeError instead of printing."""
    for s in table.SETTINGS:
        assert "%" not in s.help.replace("%%", ""), f"{s.name}: write % as %% or in words in its help"
