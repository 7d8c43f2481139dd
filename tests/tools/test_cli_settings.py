"""The command line keeps what a user gives run by run; the rarely tuned settings live in the configuration file
(firmware_model.config.SETTINGS), documented with their defaults in docs/interfaces.md section 8. The options they
replaced stay accepted, hidden, and win over the file; `--help` shows every option's default."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from firmware_model.config import load_config
from firmware_model.errors import ParameterError
from tools.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
SUBCOMMANDS = build_parser().subcommands


def visible(parser) -> list[argparse.Action]:
    return [
        a
        for a in parser._actions
        if a.option_strings and not isinstance(a, argparse._HelpAction) and a.help != argparse.SUPPRESS
    ]


#: the subcommands issue 44 counted (127 options before it); a subcommand added later has its own budget below
ISSUE44_SUBCOMMANDS = {
    "simulate", "replay", "play", "run", "plant", "diagnose", "calibrate", "bench-diagnosis", "demo", "export-c",
    "export-fmu", "status", "service-unit", "fleet",
}  # fmt: skip


#: the commands that build a gearbox: issue 45 gave each --gearbox NAME|FILE (export-c's --variant renamed)
GEARBOX_SUBCOMMANDS = ISSUE44_SUBCOMMANDS - {"play", "status", "service-unit"}


def test_at_least_a_third_fewer_options_on_the_command_line():
    """127 options before issue 44; at most 84 now, counted as /work metrics count them (hidden aliases not), less
    the --gearbox that issue 45 added to every command that builds a gearbox (export-c had --variant then) and the
    --columns that issue 46 added to the four commands that read SCADA records (replay, calibrate, diagnose,
    fleet): no other option may come back."""
    counts = {name: len(visible(p)) for name, p in SUBCOMMANDS.items() if name in ISSUE44_SUBCOMMANDS}
    assert set(counts) == ISSUE44_SUBCOMMANDS
    gearbox = {name for name, p in SUBCOMMANDS.items() if any("--gearbox" in a.option_strings for a in visible(p))}
    assert gearbox == GEARBOX_SUBCOMMANDS | {"describe", "export-dbc"}
    columns = {name for name, p in SUBCOMMANDS.items() if any("--columns" in a.option_strings for a in visible(p))}
    assert columns == {"replay", "calibrate", "diagnose", "fleet"}
    assert sum(counts.values()) - len(GEARBOX_SUBCOMMANDS) + 1 - len(columns) <= 84, counts


def test_a_later_subcommand_keeps_to_the_minimum():
    """describe (issue 45) has one option: which gearbox; export-dbc (issue 45) two: which gearbox, which file."""
    assert set(SUBCOMMANDS) - ISSUE44_SUBCOMMANDS == {"describe", "export-dbc"}
    assert [a.option_strings for a in visible(SUBCOMMANDS["describe"])] == [["--gearbox"]]
    assert [a.option_strings for a in visible(SUBCOMMANDS["export-dbc"])] == [["--gearbox"], ["--out"]]


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_help_shows_every_default(name):
    """Every option that takes a value says its default in --help, or that it has none; flags are off unless
    given and required options have none."""
    parser = SUBCOMMANDS[name]
    for action in visible(parser):
        text = " ".join(parser._get_formatter()._expand_help(action).split())
        if action.required or action.nargs == 0 or text.endswith("required"):
            continue
        assert "default" in text.lower(), f"{name} {action.option_strings[0]}: {text}"
        if action.default not in (None, [], ()):
            shown = f"{action.default:g}" if isinstance(action.default, float) else str(action.default)
            assert re.search(rf"default:? {re.escape(shown)}\b", text), (name, action.dest, text)


def _section8_settings() -> dict:
    """The commands' settings documented in docs/interfaces.md section 8: key -> value (None: commented out)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    doc = (ROOT / "docs" / "interfaces.md").read_text(encoding="utf-8")
    section = doc[doc.index("## 8. Configuration file") :]
    blocks = re.findall(r"```toml\n(.*?)```", section, re.S)
    out: dict = {}
    for block in blocks:
        body = tomllib.loads(block)
        out.update({f"{sec}.{k}": v for sec, keys in body.items() for k, v in keys.items()})
        sec = None
        for line in block.splitlines():
            m = re.match(r"\[(\w+)\]", line)
            sec = m.group(1) if m else sec
            m = re.match(r"# (\w+) = ", line)
            if m and sec:
                out.setdefault(f"{sec}.{m.group(1)}", None)
    return out


def test_every_setting_is_documented_with_its_default_and_the_option_it_replaced():
    from firmware_model.config import SETTINGS

    documented = _section8_settings()
    section = (ROOT / "docs" / "interfaces.md").read_text(encoding="utf-8").split("## 8. Configuration file")[1]
    for key, s in SETTINGS.items():
        assert key in documented, key
        assert documented[key] == s.default, (key, documented[key], s.default)
        line = next(
            li for li in section.splitlines() if re.match(rf"#? ?{key.split('.')[1]} = ", li) and s.option in li
        )
        assert line, key


def test_a_setting_out_of_range_in_the_file_is_one_sentence_naming_the_key(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[diagnosis]\ngrid_dt_s = 100.0\n")
    with pytest.raises(ParameterError, match=r"c.toml: diagnosis.grid_dt_s = 100.0 must be a number in 0.1..60"):
        load_config(cfg)
    cfg.write_text('[bench]\nsetup = "bus"\n')
    with pytest.raises(ParameterError, match=r"bench.setup = 'bus' must be 'truck' or 'rig'"):
        load_config(cfg)
    assert load_config(None).setting("fleet.period_days") == 7


def test_a_moved_option_is_hidden_and_still_accepted_over_the_file(tmp_path):
    """diagnose --grid-dt left --help for [diagnosis] grid_dt_s; given, it still wins over the file."""
    from tools.cli.settings import setting

    assert "--grid-dt" not in SUBCOMMANDS["diagnose"].format_help()
    cfg = tmp_path / "c.toml"
    cfg.write_text("[diagnosis]\ngrid_dt_s = 4.0\n")
    base = ["diagnose", "--train", "a.csv", "--test", "b.csv", "--json", "g.json", "--config", str(cfg)]
    assert setting(build_parser().parse_args(base), load_config(cfg), "diagnosis.grid_dt_s") == 4.0
    args = build_parser().parse_args([*base, "--grid-dt", "3"])
    assert setting(args, load_config(cfg), "diagnosis.grid_dt_s") == 3.0


def test_simulate_takes_its_settings_from_the_file_and_the_hidden_option_wins(tmp_path):
    """[simulate] out_dt_s = 5 gives 5 s rows; --out-dt 10 (hidden) overrides it; [cooler] kind = "hold" with
    [simulate] hold_oil_c holds the sump there."""
    from tools.runtable import read_run_table

    cfg = tmp_path / "rig.toml"
    cfg.write_text('[cooler]\nkind = "hold"\n[simulate]\nout_dt_s = 5.0\nhold_oil_c = 90.0\n')
    argv = ["simulate", "--cycle", "steady:gear=4L,rpm=1300,nm=2000,s=20", "--config", str(cfg), "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "a.csv")]) == 0
    a = read_run_table(tmp_path / "a.csv")
    assert [float(t) for t in a["time_s"][:4]] == [0.0, 5.0, 10.0, 15.0]
    assert max(abs(float(t) - 90.0) for t in a["T_oil_c"]) < 1e-9
    assert main([*argv, "--out", str(tmp_path / "b.csv"), "--out-dt", "10"]) == 0
    assert [float(t) for t in read_run_table(tmp_path / "b.csv")["time_s"][:2]] == [0.0, 10.0]


def test_fleet_vehicle_from_reads_the_path_too(tmp_path):
    """--vehicle-from took --vehicle-pattern's place: a pattern that does not match the file name is searched in
    the path (a folder in it), with optional variant and date groups; --vehicle-pattern still works, the same."""
    from tools.fleet.manifest import entries_and_rule

    for truck in ("truck1", "truck2"):
        (tmp_path / "GRS905" / truck).mkdir(parents=True)
        (tmp_path / "GRS905" / truck / "2026-01-05.log").write_text("(0.000000) vcan0 0CF00400#FFFF7D803EFFFFFF\n")
    rx = r"(?P<variant>GRS\w+)/(?P<vehicle>[^/]+)/(?P<date>[-\d]+)\.log$"
    entries, rule = entries_and_rule([tmp_path], vehicle_from=rx)
    assert sorted((e.vehicle, e.variant, e.date) for e in entries) == [
        ("truck1", "GRS905", "2026-01-05"),
        ("truck2", "GRS905", "2026-01-05"),
    ]
    assert rule == f"vehicles: 2 read from the paths by --vehicle-from '{rx}'"
    assert [e.vehicle for e in entries_and_rule([tmp_path], pattern=rx)[0]] == [e.vehicle for e in entries]
    assert "--vehicle-pattern" not in SUBCOMMANDS["fleet"].format_help()


def test_diagnosis_options_are_grouped_by_stage_and_read_as_before():
    """The 42 settings of the diagnosis in six stages; each still read, written and given by its own name."""
    from tools.diagnosis.options import STAGE_OPTIONS, Options, VerdictOptions

    o = Options(grid_dt_s=1.0, start="rest", evidence_min=6.0)
    assert (o.reading.grid_dt_s, o.starts.start, o.verdict.evidence_min) == (1.0, "rest", 6.0)
    assert (o.grid_dt_s, o.start, o.evidence_min) == (1.0, "rest", 6.0)
    o.shrink_min = 0.5
    assert o.verdict.shrink_min == 0.5 and Options(verdict=VerdictOptions(evidence_min=6.0)).evidence_min == 6.0
    assert set(STAGE_OPTIONS) == {"reading", "starts", "simulation", "fit", "verdict", "report"}
    assert sum(len(cls.__dataclass_fields__) for cls in STAGE_OPTIONS.values()) == 42
    with pytest.raises(TypeError, match="unexpected keyword argument 'grid_dt'"):
        Options(grid_dt=1.0)


def test_fleet_reads_its_settings_from_its_config(tmp_path, capsys):
    """fleet took --config ([fleet] estimates, period_days, report, and the configuration of the logs a manifest
    row gives none): a bad value is one sentence naming its key before anything runs; --period-days (hidden) still
    needs --diagnose."""
    log = tmp_path / "logs" / "truck1.log"
    log.parent.mkdir()
    log.write_text("(0.000000) vcan0 0CF00400#FFFF7D803EFFFFFF\n")
    cfg = tmp_path / "fleet.toml"
    cfg.write_text("[fleet]\nperiod_days = 0\n")
    out = tmp_path / "out"
    assert main(["fleet", str(log.parent), "--out", str(out), "--config", str(cfg)]) == 2
    assert "fleet.period_days = 0 must be a whole number of days in 1..3650" in capsys.readouterr().err
    assert main(["fleet", str(log.parent), "--out", str(out), "--period-days", "2"]) == 2
    assert "only --diagnose runs" in capsys.readouterr().err and not out.exists()


def test_the_time_to_limit_method_is_chosen_in_the_configuration(tmp_path):
    """`[sensor] ttl_method` reaches the sensor (and so every command that builds one); a wrong word is one sentence."""
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters

    params = load_parameters("GRS905")
    assert VirtualSensor(params, config=load_config(None)).sp.options.ttl_method == "bound"
    cfg = tmp_path / "march.toml"
    cfg.write_text('[sensor]\nttl_method = "march"\n')
    assert VirtualSensor(params, config=load_config(cfg)).sp.options.ttl_method == "march"
    # the caller's option wins over the file, as for the other sensor options
    assert VirtualSensor(params, config=load_config(cfg), ttl_method="bound").sp.options.ttl_method == "bound"
    cfg.write_text('[sensor]\nttl_method = "bounded"\n')
    with pytest.raises(ParameterError, match=r"sensor\.ttl_method = 'bounded' must be 'march' or 'bound'"):
        VirtualSensor(params, config=load_config(cfg))
    cfg.write_text("[sensor]\nttl_method = 1\n")
    with pytest.raises(ParameterError, match=r"sensor\.ttl_method = 1 must be a string"):
        load_config(cfg)


def test_export_fmu_says_that_export_c_s_time_to_limit_setting_is_not_its_own(tmp_path, monkeypatch, capsys):
    """[export] time_to_limit = false in the config was ignored by export-fmu without a word (the FMU still computes
    the time to limit): said on stderr, the FMU built as before."""
    import tools.export.fmu as fmu_module
    from tools.cli import main

    built = tmp_path / "s.fmu"
    monkeypatch.setattr(fmu_module, "export_fmu", lambda out, **kw: (built.write_bytes(b"x"), built)[1])
    cfg = tmp_path / "c.toml"
    cfg.write_text("[export]\ntime_to_limit = false\n")
    assert main(["export-fmu", "--config", str(cfg), "--out", str(built)]) == 0
    assert "time_to_limit = false applies to export-c" in capsys.readouterr().err
    cfg.write_text("")
    assert main(["export-fmu", "--config", str(cfg), "--out", str(built)]) == 0
    assert "time_to_limit" not in capsys.readouterr().err
