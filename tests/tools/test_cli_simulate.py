"""`gearbox-vsensor simulate`: output contract and bad input (one sentence, non-zero exit, nothing written)."""

import numpy as np
import pytest

from tools.cli import main
from tools.runtable import RunTable, read_run_table, write_run_table


def _cycle(path, **mod):
    t = np.arange(0.0, 120.0, 1.0)
    cols = {
        "time_s": t,
        "engine_speed_rpm": np.full(t.size, 1300.0),
        "engine_torque_nm": np.full(t.size, 1500.0),
        "gear": np.full(t.size, 9.0),
    }
    for k, (row, v) in mod.items():
        cols[k] = cols[k].copy()
        cols[k][row] = v
    write_run_table(RunTable(cols), path)
    return path


def test_simulate_writes_the_contract_columns(tmp_path, capsys):
    out = tmp_path / "run.csv"
    rc = main(
        [
            "simulate",
            "--cycle",
            str(_cycle(tmp_path / "c.csv")),
            "--out",
            str(out),
            "--quiet",
            "--plot",
            str(tmp_path / "p.png"),
        ]
    )
    assert rc == 0
    t = read_run_table(out)
    for c in (
        "time_s",
        "engine_speed_rpm",
        "engine_torque_nm",
        "gear",
        "oil_temp_c",
        "T_LI.teeth_c",
        "T_PS_c",
        "T_oil_c",
        "T_LS@1L_c",
        "Q_heat_total_w",
        "Q_out_cooler_w",
        "Q_out_housing_radiation_w",
    ):
        assert c in t.columns, c
    assert (tmp_path / "p.png").stat().st_size > 10000 and (tmp_path / "p_heat.png").exists()


@pytest.mark.parametrize(
    "args_mod, words",
    [
        ({"gear": (5, 17.0)}, "gear"),
        ({"engine_speed_rpm": (5, -10.0)}, "engine_speed_rpm"),
        ({"engine_torque_nm": (5, float("nan"))}, "engine_torque_nm"),
    ],
)
def test_bad_cycles_fail_cleanly(tmp_path, capsys, args_mod, words):
    out = tmp_path / "run.csv"
    rc = main(["simulate", "--cycle", str(_cycle(tmp_path / "c.csv", **args_mod)), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and words in err and "row" in err
    assert len(err.splitlines()) == 1
    assert not out.exists()


def test_missing_column_unknown_effect_bad_config(tmp_path, capsys):
    c = tmp_path / "c.csv"
    c.write_text("time_s,engine_speed_rpm,gear\n0,1000,9\n1,1000,9\n")
    out = tmp_path / "run.csv"
    assert main(["simulate", "--cycle", str(c), "--out", str(out), "--quiet"]) == 2
    assert "engine_torque_nm" in capsys.readouterr().err
    good = _cycle(tmp_path / "g.csv")
    assert main(["simulate", "--cycle", str(good), "--out", str(out), "--effect", "flux_capacitor:x=1"]) == 2
    assert "unknown effect" in capsys.readouterr().err
    assert main(["simulate", "--cycle", str(good), "--out", str(out), "--effect", "retarder_heat:fraction=0.5"]) == 2
    assert "outside" in capsys.readouterr().err
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[boundary]\nambient = 400\n")
    assert main(["simulate", "--cycle", str(good), "--out", str(out), "--config", str(cfg)]) == 2
    assert "boundary.ambient" in capsys.readouterr().err
    assert main(["simulate", "--cycle", "no_such_cycle", "--out", str(out)]) == 2
    assert not out.exists()


def test_missing_output_directory_fails_before_simulating(tmp_path, capsys):
    rc = main(["simulate", "--cycle", "mining", "--out", str(tmp_path / "no" / "run.csv"), "--quiet"])
    assert rc == 2 and "does not exist" in capsys.readouterr().err


def test_the_summary_spells_out_the_component_codes(tmp_path, capsys):
    from firmware_model.components import meaning

    rc = main(["simulate", "--cycle", "steady:gear=4L,rpm=1300,nm=2000,s=60", "--out", str(tmp_path / "s.csv")])
    out = capsys.readouterr().out.splitlines()
    assert rc == 0
    rows = out[out.index("hottest:") + 1 :][:5]
    assert len(rows) == 5
    for row in rows:
        code = row.split()[0]
        assert meaning(code) and row.endswith(meaning(code)), row


def test_churning_validity_is_not_a_note_on_every_run(tmp_path, capsys):
    """The churning correlations are outside their range for the whole of most drives (docs/validation.md says so
    once); a run notes it only when it is partial."""
    from tools.cli import main

    assert main(["simulate", "--cycle", "steady:gear=4L,rpm=1300,nm=2000,s=120", "--out", str(tmp_path / "s.csv")]) == 0
    assert "churning" not in capsys.readouterr().err


def test_an_output_on_an_input_or_on_another_output_is_refused(tmp_path, capsys):
    cyc = _cycle(tmp_path / "c.csv")
    before = cyc.read_bytes()
    assert main(["simulate", "--cycle", str(cyc), "--out", str(cyc), "--quiet"]) == 2
    assert "destroy that input" in capsys.readouterr().err
    assert cyc.read_bytes() == before
    out = tmp_path / "run.csv"
    assert main(["simulate", "--cycle", str(cyc), "--out", str(out), "--plot", str(out), "--quiet"]) == 2
    assert "would be lost" in capsys.readouterr().err
    assert main(["simulate", "--cycle", str(cyc), "--out", str(out), "--plot", str(tmp_path / "p.txt"), "--quiet"]) == 2
    assert "figure" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "col, value, words",
    [
        ("oil_temp_c", 1000.0, "start temperature"),  # the first oil reading is where every node starts
        ("oil_temp_c", -300.0, "start temperature"),
        ("bc_hot_surroundings_c", 1e6, "outside -60..250"),
        ("ambient_temp_c", -100.0, "outside -60..250"),
    ],
)
def test_implausible_start_or_boundary_temperatures_are_refused(tmp_path, capsys, col, value, words):
    t = np.arange(0.0, 120.0, 1.0)
    cols = {
        "time_s": t,
        "engine_speed_rpm": np.full(t.size, 1300.0),
        "engine_torque_nm": np.full(t.size, 1500.0),
        "gear": np.full(t.size, 9.0),
        col: np.full(t.size, 40.0),
    }
    cols[col][0] = value
    write_run_table(RunTable(cols), tmp_path / "c.csv")
    out = tmp_path / "run.csv"
    assert main(["simulate", "--cycle", str(tmp_path / "c.csv"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert col in err and words in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    "body, words",
    [
        ("[gearbox]\nvariant = 905\n", "gearbox.variant = 905 must be a string"),
        ('[gearbox]\nparams = ["a"]\n', "gearbox.params"),
        ("[sensor]\nlimits = 5\n", "sensor.limits = 5 must be a string"),
        ('[sensor]\ndebounce_s = "x"\n', "sensor.debounce_s"),
        ('[sensor]\nhysteresis_c = "3"\n', "sensor.hysteresis_c"),  # a number in quotes passed silently
        ('[gearbox]\nvariant = "GRS905"\nparams = "x.toml"\n', "not both"),
        (b"\xff\xfe\x00garbage", "not UTF-8"),
    ],
)
def test_a_config_value_of_the_wrong_type_is_one_sentence(tmp_path, capsys, body, words):
    """Each is one sentence, not a TypeError, ValueError or UnicodeDecodeError traceback."""
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(body if isinstance(body, bytes) else body.encode())
    out = tmp_path / "run.csv"
    assert (
        main(
            [
                "simulate",
                "--cycle",
                str(_cycle(tmp_path / "cyc.csv")),
                "--out",
                str(out),
                "--config",
                str(cfg),
                "--quiet",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and not out.exists()


def test_an_unknown_table_format_or_an_effect_given_twice_is_refused(tmp_path, capsys):
    """--out x.xlsx was written as CSV under that name; a second --effect of the same id silently won."""
    cyc = _cycle(tmp_path / "c.csv")
    assert main(["simulate", "--cycle", str(cyc), "--out", str(tmp_path / "x.xlsx"), "--quiet"]) == 2
    assert ".csv or .parquet" in capsys.readouterr().err and not (tmp_path / "x.xlsx").exists()
    assert (
        main(
            [
                "simulate",
                "--cycle",
                str(cyc),
                "--out",
                str(tmp_path / "x.csv"),
                "--quiet",
                "--effect",
                "churning_scale:factor=1.2",
                "--effect",
                "churning_scale:factor=1.5",
            ]
        )
        == 2
    )
    assert "given twice" in capsys.readouterr().err and not (tmp_path / "x.csv").exists()


def test_a_cycle_in_milliseconds_or_rad_s_is_refused_before_it_runs(tmp_path, capsys):
    """A CSV cycle whose time_s is in milliseconds (10-minute file -> 7 days, a 600 MB table and a 4.3 GB CAN log)
    or whose engine speed is in rad/s is refused in one sentence before the plant runs, as replay flags both;
    --allow-untrusted runs it as it is."""
    src = _cycle(tmp_path / "c.csv")
    table = read_run_table(src)
    ms = RunTable({c: (table[c] * 1000.0 if c == "time_s" else table[c]) for c in table.columns})
    rads = RunTable({c: (table[c] * 2 * np.pi / 60.0 if c == "engine_speed_rpm" else table[c]) for c in table.columns})
    t20 = np.arange(0.0, 600.0, 0.05)  # a 10-minute 20 Hz logger file in milliseconds
    ms20 = RunTable(
        {
            "time_s": t20 * 1000.0,
            "engine_speed_rpm": np.full(t20.size, 1300.0),
            "engine_torque_nm": np.full(t20.size, 1500.0),
            "gear": np.full(t20.size, 9.0),
        }
    )
    # an oil column in degF: not the sump (no --cooler measured), but every node's start without --initial-temp
    degf = RunTable(
        {**{c: ms20[c] for c in ms20.columns}, "time_s": t20, "oil_temp_c": np.linspace(176, 187, t20.size)}
    )
    for name, tab, words in (
        ("ms", ms, "if time_s is in milliseconds, give seconds"),
        ("rads", rads, "in rad/s?"),
        ("ms20", ms20, "if time_s is in milliseconds, give seconds"),
        ("degf", degf, "the oil looks like degF"),
    ):
        path = write_run_table(tab, tmp_path / f"{name}.csv")
        out = tmp_path / f"{name}_run.csv"
        assert main(["simulate", "--cycle", str(path), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err and f"{name}.csv" in err, err
        assert not out.exists()
    out = tmp_path / "rads_run.csv"
    assert (
        main(["simulate", "--cycle", str(tmp_path / "rads.csv"), "--out", str(out), "--quiet", "--allow-untrusted"])
        == 0
        and out.exists()
    )
    # a named cycle is made in the right units: the option would change nothing, so it is refused, not ignored
    out = tmp_path / "named_run.csv"
    assert main(["simulate", "--cycle", "steady", "--out", str(out), "--quiet", "--allow-untrusted"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "applies only to CSV run tables" in err and not out.exists(), err


def _figures(monkeypatch) -> list:
    """The figures the CLI writes, in order, kept for inspection (tools.plots.save_figure still writes them)."""
    import tools.plots as plots

    kept, save = [], plots.save_figure

    def keep(fig, path, *args, **kw):
        kept.append(fig)
        return save(fig, path, *args, **kw)

    monkeypatch.setattr(plots, "save_figure", keep)
    return kept


def _limit_lines(ax) -> set:
    """The y values of the horizontal lines across an axis (axhline: x from 0 to 1 in axis coordinates)."""
    return {
        float(line.get_ydata()[0])
        for line in ax.get_lines()
        if list(line.get_xdata()) == [0, 1] and len(set(line.get_ydata())) == 1 and line.get_linestyle() == "--"
    }


def test_simulate_plot_is_as_readable_as_replays(tmp_path, monkeypatch):
    """`simulate --plot` had bare codes in its legends, no warning limits and
    no input panel, where `replay --plot` and the demo have them. Both plots now draw their temperatures with one
    function (tools.plots.temperature_panel): names spelled out, each published component's warning limit."""
    from firmware_model.components import PUBLISHED, describe
    from firmware_model.onboard.warning_levels import load_limits

    limits = load_limits()
    figures = _figures(monkeypatch)
    out = tmp_path / "run.csv"
    assert (
        main(
            [
                "simulate",
                "--cycle",
                "steady:gear=4L,rpm=1300,nm=2000,s=300",
                "--out",
                str(out),
                "--quiet",
                "--plot",
                str(tmp_path / "p.png"),
            ]
        )
        == 0
    )
    fig = figures[0]  # the temperatures (the heat budget comes second)
    run = read_run_table(out)
    curves = {line.get_label(): (ax, line) for ax in fig.axes for line in ax.get_lines()}
    inputs = curves["engine speed [rpm]"][0]
    assert np.allclose(curves["engine speed [rpm]"][1].get_ydata(), run["engine_speed_rpm"])
    assert "gear (right axis)" in [t.get_text() for t in inputs.get_legend().get_texts()]
    assert np.allclose(curves["ambient air"][1].get_ydata(), run["ambient_temp_c"])
    assert "oil (sensor reading)" in curves and curves["ambient air"][0] is not inputs
    drawn = [c for c in PUBLISHED if c != "oil" and describe(c) in curves]
    assert len(drawn) == len(PUBLISHED) - 1  # every published component, each with its name spelled out
    legends = {t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()}
    assert "PS (sun wheel)" in legends and not legends & set(PUBLISHED)
    for c in drawn:
        ax = curves[describe(c)][0]
        assert limits.of(c)[0] in _limit_lines(ax), c
    figures.clear()  # replay's plot: the same panel, the same limits
    assert (
        main(["replay", str(out), "--out", str(tmp_path / "est.csv"), "--quiet", "--plot", str(tmp_path / "r.png")])
        == 0
    )
    temps = figures[0].axes[1]
    shown = [line.get_label() for line in temps.get_lines() if not line.get_label().startswith("_")]
    codes = [c for c in PUBLISHED if describe(c) in shown]
    assert codes and {limits.of(c)[0] for c in codes} <= _limit_lines(temps)


def test_start_time_gives_the_can_log_unix_frame_times(tmp_path, capsys):
    """`simulate --can-log` logs started at 0 s, so `fleet` could not date them; --start-time ISO starts
    the frame times at that UTC time; without --can-log, or not a time: one sentence, nothing written."""
    import datetime as dt

    log = tmp_path / "run.log"
    args = ["simulate", "--cycle", str(_cycle(tmp_path / "c.csv")), "--out", str(tmp_path / "run.csv"), "--quiet"]
    assert main([*args, "--can-log", str(log), "--start-time", "2026-01-05T08:00:00+01:00"]) == 0
    first_s = float(log.read_text().split(")", 1)[0].strip("("))
    assert first_s == dt.datetime(2026, 1, 5, 7, tzinfo=dt.timezone.utc).timestamp()
    for extra, words in (
        (["--start-time", "2026-01-05"], "only --can-log writes"),
        (["--can-log", str(tmp_path / "b.log"), "--start-time", "monday"], "not an ISO 8601"),
    ):
        assert main([*args[:-3], "--out", str(tmp_path / "b.csv"), "--quiet", *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and len(err.splitlines()) == 1, err
        assert not (tmp_path / "b.csv").exists() and not (tmp_path / "b.log").exists()


def test_an_effect_the_runs_cooler_makes_act_on_nothing_is_refused(tmp_path, capsys):
    """thermostat_offset on the default liquid cooler (no thermostat) changed no node and exited 0: a run that asked
    for the effect passed for one with it."""
    out = tmp_path / "x.csv"
    argv = [
        "simulate",
        "--cycle",
        "steady:s=30",
        "--out",
        str(out),
        "--quiet",
        "--effect",
        "thermostat_offset:offset_c=10",
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--effect thermostat_offset acts on air coolers, and this run's cooler is liquid" in err and not out.exists()
    cfg = tmp_path / "air.toml"
    cfg.write_text('[cooler]\nkind = "air"\n')
    assert main([*argv, "--config", str(cfg)]) == 0 and out.exists()


@pytest.mark.parametrize(
    "effect, words",
    [
        ("planetary_loss_scale:factor=1.3", "acts on a planetary set, and gearbox HR225 has none"),
        ("hot_surroundings_offset:offset_c=10", "acts on a hot_surroundings boundary, and gearbox HR225 has none"),
        ("synchronizer_shift_heat:energy_j=1000", "acts on a synchronizer, and gearbox HR225 has none"),
    ],
)
def test_an_effect_on_a_part_the_gearbox_lacks_is_refused(tmp_path, capsys, effect, words):
    """planetary_loss_scale and hot_surroundings_offset on a user's 6-speed gearbox changed nothing (0.0000 K)
    and exited 0: a run that asked for the effect passed for one with it."""
    cyc = _fixed_ratio_cycle(tmp_path / "c.csv", 1480.0, 600.0, s=60)
    out = tmp_path / "x.csv"
    argv = ["simulate", "--gearbox", "HR225", "--cycle", str(cyc), "--out", str(out), "--quiet", "--effect", effect]
    assert main(argv) == 2
    assert words in capsys.readouterr().err and not out.exists()


def test_a_named_cycle_setting_in_the_config_is_said_to_be_ignored_for_a_run_table(tmp_path, capsys):
    """[simulate] rate_hz in a project's configuration with a CSV cycle changed nothing without a word (the option
    is refused): a warning names the key and the file; the run goes on (the file serves named cycles too)."""
    cfg = tmp_path / "p.toml"
    cfg.write_text("[simulate]\nrate_hz = 5\nnoise = true\n")
    out = tmp_path / "run.csv"
    assert (
        main(
            ["simulate", "--cycle", str(_cycle(tmp_path / "c.csv")), "--config", str(cfg), "--out", str(out), "--quiet"]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert "warning: [simulate] rate_hz, [simulate] noise in" in err and "apply only to named cycles" in err
    assert out.exists()


def test_a_sump_held_warm_beside_cold_parts_is_a_note(tmp_path, capsys):
    """[simulate] hold_oil_c = 100 on a steady spec without init: the sump at 100 degC, every other part from the
    spec's 20 degC, without a word (steady:...,oil=100 starts them all at 100)."""
    cfg = tmp_path / "h.toml"
    cfg.write_text('[cooler]\nkind = "hold"\n[simulate]\nhold_oil_c = 100\n')
    out = tmp_path / "run.csv"
    assert main(["simulate", "--cycle", "steady:s=30", "--config", str(cfg), "--out", str(out), "--quiet"]) == 0
    assert "note: the sump is held at 100 degC while the other parts start at 20 degC" in capsys.readouterr().err
    assert main(["simulate", "--cycle", "steady:s=30,oil=100", "--out", str(out), "--quiet"]) == 0
    assert "held at" not in capsys.readouterr().err


def _fixed_ratio_cycle(path, rpm: float, nm: float, s: int = 300):
    """A fixed-ratio drive's CSV cycle: constant input speed and torque at 20 degC ambient."""
    t = np.arange(0.0, s + 1.0, 1.0)
    cols = {
        "time_s": t,
        "input_speed_rpm": np.full(t.size, rpm),
        "input_torque_nm": np.full(t.size, nm),
        "ambient_temp_c": np.full(t.size, 20.0),
    }
    write_run_table(RunTable(cols), path)
    return path


def test_plots_of_another_gearbox_draw_its_own_limits(tmp_path, monkeypatch):
    """`simulate --plot` and `replay --plot` looked up every published component in the GRS905's limits, so
    every other gearbox (R1, HR225, MM82, a user's own) stopped with 'tuple.index(x): x not in tuple' and wrote
    no CSV either. The plots now draw the limits the gearbox's own description names (here a file beside it)."""
    from firmware_model.parameters import PARAM_DIR

    gb = tmp_path / "R1own.toml"
    gb.write_text(
        (PARAM_DIR / "R1.toml")
        .read_text(encoding="utf-8")
        .replace(
            "[topology.published]\n", '[topology.published]\nlimits = { v = "own.toml", u = "-", src = "assumed" }\n'
        )
    )
    own = {"gear": 111.0, "sun": 121.0, "planetary": 122.0, "bearing": 101.0, "oil": 91.0}
    (tmp_path / "own.toml").write_text(
        "".join(
            f'[{g}]\nwarning = {{ v = {w}, u = "degC", src = "assumed" }}\n'
            f'critical = {{ v = {w + 10}, u = "degC", src = "assumed" }}\n'
            f'hysteresis = {{ v = 2, u = "K", src = "assumed" }}\n'
            for g, w in own.items()
        )
    )
    cyc = _fixed_ratio_cycle(tmp_path / "c.csv", 1000.0, 200.0)
    figures = _figures(monkeypatch)
    out = tmp_path / "run.csv"
    args = ["simulate", "--gearbox", str(gb), "--cycle", str(cyc), "--out", str(out), "--quiet"]
    assert main([*args, "--plot", str(tmp_path / "p.png")]) == 0
    assert out.exists() and (tmp_path / "p.png").exists()
    drawn = set().union(*(_limit_lines(ax) for ax in figures[0].axes))
    assert drawn == {own["gear"], own["bearing"]}, drawn  # the R1's wheels and bearings (its oil has no panel)
    figures.clear()
    rep = ["replay", "--gearbox", str(gb), str(cyc), "--out", str(tmp_path / "est.csv"), "--quiet"]
    assert main([*rep, "--allow-untrusted", "--plot", str(tmp_path / "r.png")]) == 0  # no oil reading: degraded
    assert (tmp_path / "r.png").exists()
    assert _limit_lines(figures[0].axes[1]) <= {own["gear"], own["bearing"], own["oil"]}
    assert _limit_lines(figures[0].axes[1])


def test_a_fixed_ratio_table_s_bad_value_is_named_by_its_own_column(tmp_path, capsys):
    """A torque beyond the HR225's drive limits was said of "column engine_torque_nm", a column the user's table
    does not have (it has input_torque_nm)."""
    cyc = _fixed_ratio_cycle(tmp_path / "c.csv", 1480.0, 5000.0, s=60)
    assert main(["simulate", "--gearbox", "HR225", "--cycle", str(cyc), "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "column input_torque_nm row 1 (line 2): 5000 Nm is outside the input shaft's range" in err, err


def test_plot_of_a_derived_temperature_draws_no_limit(tmp_path):
    """The MM82's forced oil inlet (a derived temperature, no node of the sensor, so no limit of its own) is in
    its plant table: `simulate --plot` draws it without a limit rather than failing to find one."""
    cyc = _fixed_ratio_cycle(tmp_path / "c.csv", 10.0, 1.5e6, s=120)
    out = tmp_path / "run.csv"
    args = ["simulate", "--gearbox", "MM82", "--cycle", str(cyc), "--out", str(out), "--quiet"]
    assert main([*args, "--plot", str(tmp_path / "p.png")]) == 0
    assert "T_oil.inlet_c" in read_run_table(out, required=("time_s",)).columns and (tmp_path / "p.png").exists()


def _without_top_gears(tmp_path):
    """The GRS905's file without gears 9..14 (4L..6H): a gearbox whose gears are -2..8."""
    import re

    from firmware_model.parameters import PARAM_DIR

    text = (PARAM_DIR / "GRS905.toml").read_text()
    for name in ("4L", "4H", "5L", "5H", "6L", "6H"):
        text = re.sub(rf"^\[topology\.gear\.{name}\]\n(?:(?!\[).*\n)*", "", text, flags=re.M)
    path = tmp_path / "LOW8.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "cycle, words",
    [
        ("steady:gear=12,rpm=1500,nm=2000,s=600", "steady cycle spec 'steady:gear=12,rpm=1500,nm=2000,s=600': gear=12"),
        ("csv", "column gear row 6 (time_s 5 s): gear 12"),
    ],
)
def test_a_gear_the_gearbox_does_not_have_is_refused(tmp_path, capsys, cycle, words):
    """A gear number the description has no gear for ran as neutral's row: the engine's power vanished without a
    mesh loss (a 6-speed gearbox's gear 7: 314 kW in, no mesh heat), exit 0. Now one sentence naming the gear,
    where, and the gearbox's gears; exit 2. (A named road cycle is fitted to the gearbox's own gears instead:
    tests/tools/test_cycles_other_gearbox.py.)"""
    gearbox = _without_top_gears(tmp_path)
    if cycle == "csv":
        t = np.arange(0.0, 20.0, 1.0)
        gear = np.full(t.size, 8.0)
        gear[5] = 12.0
        cycle = str(tmp_path / "c.csv")
        write_run_table(
            RunTable(
                {"time_s": t, "engine_speed_rpm": t * 0 + 1300.0, "engine_torque_nm": t * 0 + 1500.0, "gear": gear}
            ),
            cycle,
        )
    out = tmp_path / "run.csv"
    rc = main(["simulate", "--gearbox", str(gearbox), "--cycle", cycle, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert words in err and ("-2, -1, 0, 1, 2, 3, 4, 5, 6, 7, 8" in err or "8 (3H)" in err), err
    assert not out.exists()


def test_a_can_log_of_a_cycle_with_its_own_boundaries_says_it_cannot_carry_them(capsys):
    """An effect-free uphill drive written as a CAN log was diagnosed as hot_surroundings_offset +29.5 K: the cycle's
    engine-side boundaries (hot surroundings 100 degC) are in no frame, so the log's reader takes the gearbox's
    own (90). simulate --can-log says so; a steady spec at the gearbox's own boundaries says nothing."""
    from firmware_model.description import load_description
    from tools.cycles.named import boundaries_a_log_cannot_carry, get_cycle

    d = load_description("GRS905")
    note = boundaries_a_log_cannot_carry(get_cycle("uphill", description=d), d)
    assert note.startswith("carries no boundary temperatures") and "hot_surroundings 100 (its own 90)" in note
    assert boundaries_a_log_cannot_carry(get_cycle("steady:s=20", description=d), d) is None


@pytest.mark.parametrize("kind", ["liquid", "air", "none", "measured"])
def test_a_held_sump_of_the_cycle_with_a_configured_cooler_is_refused(tmp_path, capsys, kind):
    """steady:...,oil=60 with [cooler] kind = "liquid" held the sump at 60 degC and the liquid cooler took no part
    (its heat 0 W), without a word, where [simulate] hold_oil_c with that cooler is refused; with "measured" the
    oil= was dropped instead. One sentence, exit 2, nothing written."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'[cooler]\nkind = "{kind}"\n')
    out = tmp_path / "s.csv"
    argv = ["simulate", "--cycle", "steady:s=30,oil=60", "--config", str(cfg), "--out", str(out), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "the cycle steady:s=30,oil=60 holds the sump at 60 degC (its oil=)" in err, err
    assert f"this run's cooler is {kind}" in err and "leave oil= out" in err and not out.exists()
    argv[1:3] = ["--cycle", "all_gears"]  # a cycle that always holds its sump: no oil= to leave out
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "the cycle all_gears holds the sump at 100 degC" in err and "oil=" not in err and not out.exists()
    from firmware_model.errors import InputError
    from tools.can.hil import prepare

    with pytest.raises(InputError, match=f"this run's cooler is {kind}"):  # `plant` (HIL) runs the same plant
        prepare("steady:s=30,oil=60", cfg)


def test_the_cycles_oil_holds_the_sump_in_place_of_the_gearbox_cooler(tmp_path, capsys):
    """Without a configured cooler (or with "hold") the spec's oil= holds the sump, in place of the description's
    liquid cooler: the sump stays at 60 degC, the cooler carries no heat, the held sump takes it; a [simulate]
    hold_oil_c that differs from oil= is refused (it silently won)."""
    out = tmp_path / "s.csv"
    argv = ["simulate", "--cycle", "steady:s=600,oil=60", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    t = read_run_table(out)
    assert np.max(np.abs(np.asarray(t["T_oil_c"], dtype=float) - 60.0)) < 1e-9
    assert np.all(np.asarray(t["Q_out_cooler_w"], dtype=float) == 0.0)
    assert np.asarray(t["Q_out_oil_boundary_w"], dtype=float)[-1] > 1000.0  # the losses leave through the hold
    cfg = tmp_path / "h.toml"
    cfg.write_text('[cooler]\nkind = "hold"\n[simulate]\nhold_oil_c = 90\n')
    assert main([*argv, "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "holds the sump at 60 degC (its oil=)" in err and "hold_oil_c 90 degC" in err
    cfg.write_text('[cooler]\nkind = "hold"\n')
    assert main([*argv, "--config", str(cfg)]) == 0
    assert np.max(np.abs(np.asarray(read_run_table(out)["T_oil_c"], dtype=float) - 60.0)) < 1e-9


def test_a_run_that_leaves_the_oil_model_says_so_quiet_or_not(tmp_path, capsys):
    """The HR225 (no heater, VG 220) started at -20 degC at rated load: its bearings' losses, taken at the cold
    sump's viscosity, put them above the 200 degC the oil's properties are defined to (docs/physics.md, "Oil
    properties"); the run says so, also with --quiet. From 20 degC, nothing is said."""
    cyc = _fixed_ratio_cycle(tmp_path / "cold.csv", 1485.0, 700.0, s=600)
    cyc.write_text(cyc.read_text().replace(",20.0\n", ",-20.0\n"))
    cfg = tmp_path / "cold.toml"
    cfg.write_text("[simulate]\ninitial_temp_c = -20\n")
    out = tmp_path / "run.csv"
    args = ["simulate", "--gearbox", "HR225", "--cycle", str(cyc), "--config", str(cfg), "--out", str(out), "--quiet"]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "degC the oil's properties are defined to: the run has left the model there" in err
    head = out.read_text().splitlines()[0].split(",")
    cols = [i for i, c in enumerate(head) if c.startswith("T_") and c.endswith("_c")]
    assert np.loadtxt(out, delimiter=",", skiprows=1, usecols=cols).max() > 200.0  # what the note is about
    warm = _fixed_ratio_cycle(tmp_path / "warm.csv", 1485.0, 700.0, s=600)
    assert main(["simulate", "--gearbox", "HR225", "--cycle", str(warm), "--out", str(out), "--quiet"]) == 0
    assert "left the model" not in capsys.readouterr().err


def test_a_fixed_ratio_gearbox_takes_a_steady_spec_of_its_input_shaft(tmp_path, capsys):
    """A rig's steady point on the HR225 needed a CSV written by hand ('is a truck's'); the spec holds its input
    shaft: the same run as the CSV of that speed, torque and air. rpm= and nm= are both asked for, gear= refused.
    Its air is ambient=, else the description's ambient (HR225: 25 degC; it took the truck's 20: a trial)."""
    out, csv_out = tmp_path / "s.csv", tmp_path / "c.csv"
    assert main(["simulate", "--gearbox", "HR225", "--cycle", "steady:rpm=1480,nm=700,s=60", "--out", str(out)]) == 0
    assert set(np.asarray(read_run_table(out, required=("time_s",))["ambient_temp_c"])) == {25.0}
    spec = "steady:rpm=1480,nm=700,s=600,ambient=20"
    assert main(["simulate", "--gearbox", "HR225", "--cycle", spec, "--out", str(out), "--quiet"]) == 0
    cyc = _fixed_ratio_cycle(tmp_path / "rig.csv", 1480.0, 700.0, s=600)
    assert main(["simulate", "--gearbox", "HR225", "--cycle", str(cyc), "--out", str(csv_out), "--quiet"]) == 0
    a, b = read_run_table(out, required=("time_s",)), read_run_table(csv_out, required=("time_s",))
    t_a, t_b = np.asarray(a["time_s"]), np.asarray(b["time_s"])
    both = np.intersect1d(t_a, t_b)
    assert both.size > 500
    np.testing.assert_allclose(
        np.asarray(a["T_oil_c"])[np.isin(t_a, both)], np.asarray(b["T_oil_c"])[np.isin(t_b, both)], atol=1e-6
    )
    for bad, words in (
        ("steady:rpm=1480", "give rpm= and nm= of gearbox HR225's input shaft"),
        ("steady:gear=1,rpm=1480,nm=700", "gearbox HR225 has one gear; leave gear= out"),
        ("steady:rpm=5000,nm=700", "rpm=5000 must be in 0..1800"),
    ):
        assert main(["simulate", "--gearbox", "HR225", "--cycle", bad, "--out", str(out)]) == 2
        assert words in capsys.readouterr().err


def test_a_cycle_with_gaps_between_its_rows_is_noted(tmp_path, capsys):
    """5 minutes cut from a climb were simulated at the load before them, in silence, while replay took the engine as
    off after 60 s (a validation trial): simulate names the gaps in a note; a cycle without gaps has none."""
    from tools.cli.simulate import gap_note

    t = np.r_[np.arange(0.0, 60.0, 0.1), 360.0 + np.arange(0.0, 60.0, 0.1)]
    note = gap_note(RunTable({"time_s": t}), "c.csv")
    assert note.startswith("c.csv: 1 gap between rows (the longest 300 s after 59.9 s)") and "60 s" in note
    assert gap_note(RunTable({"time_s": np.arange(0.0, 60.0, 0.1)}), "c.csv") == ""
    assert gap_note(RunTable({"time_s": np.r_[np.arange(0.0, 60.0, 0.1), 65.0]}), "c.csv") == ""  # 5 s: no gap
