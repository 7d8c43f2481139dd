"""The command line's options: a mistyped option is refused by its subcommand with a suggestion, usages are honest,
an option that would do nothing in the mode given is an error (nothing written), and `plant` checks its bus before
it computes the drive."""

from __future__ import annotations

import argparse

import pytest

from tools.cli import build_parser, main

#: the shortest command line each subcommand accepts
MINIMAL = {
    "simulate": ["--cycle", "uphill", "--out", "r.csv"],
    "replay": ["r.csv", "--out", "e.csv"],
    "play": ["r.log", "--interface", "virtual", "--channel", "x"],
    "run": ["--interface", "virtual", "--channel", "x"],
    "plant": ["--interface", "virtual", "--channel", "x", "--cycle", "uphill"],
    "diagnose": ["--train", "a.csv", "--test", "b.csv", "--json", "g.json"],
    "calibrate": ["--train", "a.csv", "--test", "b.csv", "--auto", "--out", "c.toml"],
    "bench-diagnosis": [],
    "demo": [],
    "export-c": ["--out", "d"],
    "export-fmu": ["--out", "v.fmu"],
    "status": [],
    "service-unit": [],
    "fleet": ["logs/", "--out", "fleet_out"],
    "describe": [],
    "export-dbc": [],
}
SUBCOMMANDS = build_parser().subcommands


def long_options(parser) -> list[str]:
    """The options --help shows (not the hidden ones that moved to the configuration)."""
    return [
        o
        for a in parser._actions
        if a.help != argparse.SUPPRESS
        for o in a.option_strings
        if o.startswith("--") and o != "--help"
    ]


def test_every_subcommand_has_a_minimal_command_line():
    assert set(MINIMAL) == set(SUBCOMMANDS)
    for name, argv in MINIMAL.items():
        build_parser().parse_args([name, *argv])


@pytest.mark.parametrize("name", sorted(MINIMAL))
def test_a_mistyped_option_is_refused_by_its_subcommand_with_a_suggestion(name, capsys):
    option = long_options(SUBCOMMANDS[name])[-1]
    typo = option[:-1] + option[-1] * 2 + "x"
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args([name, *MINIMAL[name], typo])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.startswith(f"usage: gearbox-vsensor {name} ")
    assert f"gearbox-vsensor {name}: error: unrecognized arguments: {typo} (did you mean {option}?)" in err


def test_a_mistyped_required_option_is_named_with_its_suggestion(capsys):
    """`--outt` for the required `--out`: the missing option alone ("required: --out") hid the typo."""
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["simulate", "--cycle", "uphill", "--outt", "e.csv"])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert (
        "error: unrecognized arguments: --outt (did you mean --out?); the following arguments are required: --out"
        in err
    )
    with pytest.raises(SystemExit):  # an abbreviation argparse accepts is not called unknown
        build_parser().parse_args(["simulate", "--cyc", "uphill"])
    err = capsys.readouterr().err
    assert "required: --out" in err and "unrecognized" not in err


def test_an_extra_argument_is_refused_by_its_subcommand(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["simulate", "--cycle", "uphill", "--out", "e.csv", "b.csv"])
    err = capsys.readouterr().err
    assert err.startswith("usage: gearbox-vsensor simulate ") and "unrecognized arguments: b.csv" in err
    assert "did you mean" not in err


def test_replay_of_several_files_without_a_column_map_is_one_sentence(tmp_path, capsys):
    # several files are one record only for SCADA (--columns); a second run table or log is refused, not ignored
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["replay", str(a), str(b), "--out", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert "replay reads one run table or CAN log, not 2 files" in err and err.count("error:") == 1


def test_replay_usage_is_honest_and_complete():
    usage = SUBCOMMANDS["replay"].format_usage()
    assert "[--out" not in usage and usage.count("--out EST.csv") == 3
    assert "--realtime" not in usage and "--interface" not in usage
    for option in long_options(SUBCOMMANDS["replay"]):
        assert option in usage, option


def test_replay_processes_was_removed_and_says_what_replaced_it(tmp_path, capsys):
    log = tmp_path / "run.log"
    log.write_text("(0.000000) vcan0 0CF00400#FFFF7D803EFFFFFF\n")
    with pytest.raises(SystemExit) as exc:
        main(["replay", str(log), "--out", str(tmp_path / "e.csv"), "--processes", "2"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "error: --processes was removed: a CAN log without --frames-out is replayed as a whole log" in err
    assert err.count("error:") == 1 and not (tmp_path / "e.csv").exists()


@pytest.fixture
def files(tmp_path):
    from tools.runtable import RunTable, write_run_table

    csv = write_run_table(
        RunTable(
            {
                "time_s": [0.0, 1.0],
                "engine_speed_rpm": [800.0, 800.0],
                "engine_torque_nm": [100.0, 100.0],
                "gear": [9.0, 9.0],
            }
        ),
        tmp_path / "run.csv",
    )
    log = tmp_path / "run.log"
    log.write_text("(0.000000) vcan0 0CF00400#FFFF7D803EFFFFFF\n")
    return tmp_path, csv, log


@pytest.mark.parametrize(
    "extra, named",
    [
        (["--frames-out", "F.log"], "--frames-out"),
        (["--strict"], "--strict"),
        (["--frames-out", "F.log", "--strict"], "--frames-out, --strict"),
    ],
)
def test_replay_refuses_log_options_on_a_run_table(files, capsys, extra, named):
    d, csv, _ = files
    out = d / "est.csv"
    extra = [str(d / a) if a.endswith(".log") else a for a in extra]
    assert main(["replay", str(csv), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"gearbox-vsensor replay: error: {named} do") and err.count("\n") == 0
    assert not out.exists()


@pytest.mark.parametrize(
    "extra",
    [
        ["--realtime", "--interface", "virtual", "--channel", "x"],
        ["--realtime", "--interface", "virtual", "--channel", "x", "--speed", "10"],
        ["--out", "OUT", "--speed", "3"],
    ],
)
def test_replay_realtime_points_to_play(files, capsys, extra):
    """`replay --realtime` became `play`: an old command line exits 2 with one sentence naming the new one."""
    d, _, log = files
    extra = [str(d / "est.csv") if a == "OUT" else a for a in extra]
    with pytest.raises(SystemExit) as exc:
        main(["replay", str(log), *extra])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "error: replay --realtime is now its own command: gearbox-vsensor play LOG --interface NAME" in err
    assert err.count("error:") == 1 and not (d / "est.csv").exists()


@pytest.mark.parametrize("extra, named", [(["--seed", "3"], "--seed"), (["--rate", "5", "--noise"], "--rate, --noise")])
def test_simulate_refuses_cycle_options_on_a_run_table(files, capsys, extra, named):
    d, csv, _ = files
    assert main(["simulate", "--cycle", str(csv), "--out", str(d / "s.csv"), *extra]) == 2
    assert f"error: {named} appl" in capsys.readouterr().err and not (d / "s.csv").exists()


def test_simulate_refuses_a_held_sump_with_another_cooler(tmp_path, capsys):
    argv = [
        "simulate",
        "--cycle",
        "steady:gear=4L,rpm=1300,nm=2000,s=20",
        "--out",
        str(tmp_path / "s.csv"),
        "--quiet",
        "--hold-oil",
        "100",
    ]
    assert main([*argv, "--cooler", "liquid"]) == 2
    assert "--hold-oil" in capsys.readouterr().err and not (tmp_path / "s.csv").exists()
    assert main([*argv, "--cooler", "hold", "--seed", "1"]) == 0


@pytest.mark.parametrize(
    "argv, named",
    [
        (["--setup", "truck"], "--setup"),
        (["--cooler", "air"], "--cooler"),
        (["--effect", "none", "--scenarios", "3"], "--scenarios"),
        (["--effect", "none", "--only", "1"], "--only"),
    ],
)
def test_bench_diagnosis_refuses_options_of_the_other_mode(tmp_path, capsys, argv, named):
    assert main(["bench-diagnosis", "--out", str(tmp_path / "b"), *argv]) == 2
    assert f"error: {named} " in capsys.readouterr().err and not (tmp_path / "b").exists()


def test_bench_diagnosis_refuses_a_start_for_the_model_form_family(tmp_path, capsys):
    assert main(["bench-diagnosis", "--out", str(tmp_path / "b"), "--family", "model-form", "--start", "rest"]) == 2
    assert "error: --start applies to" in capsys.readouterr().err and not (tmp_path / "b").exists()


def test_bench_diagnosis_counts_the_files_taken_running():
    """The bench row counts a scenario's files scored as starting running (the JSON's starts), for its table."""
    from tools.diagnosis.bench import Scenario, format_table, score_row, summarize

    res = {
        "verdict": {"effect": "none", "shrink": 0.0, "test_rms_before_c": 0.1, "test_rms_after_c": 0.1},
        "identifiability": {},
        "starts": {"a.csv": {"start": "running"}, "b.csv": {"start": "rest"}, "test:a.csv": {"start": "running"}},
    }
    row = score_row(Scenario(0, 1, "truck", None, None, "liquid"), res, 1.0)
    assert (row.files, row.running, row.ok) == (3, 2, True)
    assert "| files scored as starting while the gearbox runs (--start) | 2 of 3 |" in format_table(
        [row], summarize([row])
    )


def test_bench_diagnosis_refuses_scenarios_outside_the_plan(tmp_path, capsys):
    """--only 999 of a 2-scenario plan is refused, not a run of nothing that writes a table of NaN with exit 0."""
    assert main(["bench-diagnosis", "--out", str(tmp_path / "b"), "--scenarios", "2", "--only", "1,999"]) == 2
    assert "no scenario 999 in a plan of 2" in capsys.readouterr().err and not (tmp_path / "b").exists()


def test_plant_checks_the_bus_before_it_computes_the_drive(monkeypatch, capsys):
    import tools.can.hil

    calls = []

    def prepare(*args, **kwargs):
        calls.append(args)
        raise AssertionError("the drive was computed before the bus was opened")

    monkeypatch.setattr(tools.can.hil, "prepare", prepare)
    rc = main(["plant", "--interface", "no_such_interface", "--channel", "x", "--cycle", "uphill", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and calls == [] and "no_such_interface" in err and err.count("\n") == 1


def test_run_refuses_a_state_period_without_a_state_file(capsys):
    """--state-period without --state-file is refused: alone it would do nothing, silently."""
    assert main(["run", "--interface", "virtual", "--channel", "x", "--state-period", "5"]) == 2
    assert "give --state-file too" in capsys.readouterr().err


def test_a_subcommand_builds_and_imports_only_its_own_parser():
    """`gearbox-vsensor run ...` imports tools.cli.run and none of the other subcommands' modules (the service's
    start-up); an unknown or no subcommand builds them all, for the list of choices."""
    import subprocess
    import sys

    code = (
        "import sys; from tools.cli import main\n"
        "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in sys.modules if m.startswith('tools.cli.')))"
    )

    def modules(*argv):
        out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, check=True).stdout
        return out.strip().splitlines()[-1]

    one = modules("service-unit", "--help")
    assert "tools.cli.service_unit" in one and "tools.cli.simulate" not in one and "tools.cli.diagnose" not in one
    every = modules("servce-unit")
    assert "tools.cli.simulate" in every and "tools.cli.diagnose" in every and "tools.cli.service_unit" in every
