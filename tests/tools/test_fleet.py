"""`gearbox-vsensor fleet` on Dask: a real multi-process cluster, a worker killed mid-run, bad logs, re-runs, bad
input. Needs dask.distributed and pyarrow (pip install '.[fleet]'); without them these tests skip and say so.

Every Dask client runs in a child process: a Dask client leaves threads behind in its process, and other tests of
this session (the two-process replay) must be able to fork this one."""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

if importlib.util.find_spec("distributed") is None or importlib.util.find_spec("pyarrow") is None:
    pytest.skip("the fleet tests need dask.distributed and pyarrow: pip install '.[fleet]'", allow_module_level=True)

import pyarrow.parquet as pq  # noqa: E402

from firmware_model.errors import InputError  # noqa: E402
from firmware_model.service import build_service  # noqa: E402
from tools.cli import main  # noqa: E402
from tools.fleet.manifest import read_manifest  # noqa: E402
from tools.fleet.store import ERRORS, read_table  # noqa: E402
from tools.fleet.summary import summarize  # noqa: E402
from tools.fleet.synth import FleetSpec, synth_fleet  # noqa: E402
from tools.replay.log import replay_log  # noqa: E402

ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """3 trucks x 3 days of 2-minute logs, one with a fouling cooler."""
    root = tmp_path_factory.mktemp("fleet")
    manifest = synth_fleet(root / "logs", FleetSpec(vehicles=3, days=3, minutes=2.0, fouling=1, seed=2), processes=1)
    return manifest


def _rows(out) -> dict:
    t = read_table(out)
    rows = t.to_pylist()
    return {r["log_key"]: r for r in rows}


def _same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        for col, va in a[k].items():
            if col == "replayed_at_s":  # when the row was made
                continue
            vb = b[k][col]
            assert va == vb or (isinstance(va, float) and np.isnan(va) and np.isnan(vb)), (col, va, vb)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_workers(address: str, n: int, timeout_s: float = 60.0) -> None:
    code = (
        f"from dask.distributed import Client\nwith Client({address!r}, timeout='30s') as c:\n"
        f"    c.wait_for_workers({n}, timeout={timeout_s})\n"
    )
    subprocess.run([sys.executable, "-c", code], env=ENV, check=True, timeout=timeout_s + 30)


def fleet(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    """`gearbox-vsensor fleet ARGS` in a child process."""
    res = subprocess.run(
        [sys.executable, "-m", "tools.cli", "fleet", *args], env=ENV, capture_output=True, text=True, timeout=600
    )
    if check:
        assert res.returncode == 0, res.stderr[-3000:]
    return res


def run_fleet_in_child(tmp_path, body: str) -> None:
    """Run ``body`` (Python using run_fleet, read_manifest, os, signal) as a script in a child process."""
    script = tmp_path / "child.py"
    script.write_text(
        "import os, signal\nfrom tools.fleet.manifest import read_manifest\n"
        "from tools.fleet.run import run_fleet\n\nif __name__ == '__main__':\n"
        + textwrap.indent(textwrap.dedent(body), "    ")
    )
    res = subprocess.run([sys.executable, str(script)], env=ENV, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]


@pytest.fixture()
def cluster(tmp_path):
    """`dask scheduler` and two `dask worker` processes (no nanny: a SIGKILL kills the worker itself)."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [
        subprocess.Popen(
            [*dask, "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            env=ENV,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            cwd=tmp_path,
        )
    ]
    time.sleep(1.0)
    for _ in range(2):
        procs.append(
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "distributed.cli.dask_worker",
                    address,
                    "--nthreads",
                    "1",
                    "--no-nanny",
                    "--no-dashboard",
                ],
                env=ENV,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                cwd=tmp_path,
            )
        )
    try:
        _wait_workers(address, 2)
        yield address, procs[1:]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=30)


def test_a_real_cluster_gives_the_local_clusters_rows_and_per_log_replay(tmp_path, synthetic, cluster):
    address, _ = cluster
    entries = read_manifest(synthetic)
    fleet(
        "--manifest",
        str(synthetic),
        "--out",
        str(tmp_path / "remote"),
        "--scheduler",
        address,
        "--estimates",
        "--no-report",
    )
    fleet("--manifest", str(synthetic), "--out", str(tmp_path / "local"), "--workers", "1", "--no-report")
    remote, local = _rows(tmp_path / "remote"), _rows(tmp_path / "local")
    assert len(remote) == len(entries)
    _same(remote, local)
    # per-log replay: the same table as the fleet's estimates and the same summary row
    e = entries[4]
    est = pq.read_table(next((tmp_path / "remote" / "estimates").rglob(f"*{e.key}.parquet")))
    assert main(["replay", str(e.log), "--out", str(tmp_path / "one.parquet"), "--quiet"]) == 0
    one = pq.read_table(tmp_path / "one.parquet")
    assert est.column_names == one.column_names
    for c in one.column_names:
        assert np.array_equal(est.column(c).to_numpy(), one.column(c).to_numpy(), equal_nan=True), c
    table = replay_log(e.log, build_service(None, record=True, emit_frames=False, log_findings=False))
    row = summarize(table, table.meta["counters"], vehicle=e.vehicle, log=os.fspath(e.log), key=e.key)
    _same({e.key: {k: v for k, v in row.items()}}, {e.key: remote[e.key]})


def test_a_worker_killed_mid_run_every_log_once(tmp_path, synthetic, cluster):
    address, workers = cluster
    entries = read_manifest(synthetic)
    run_fleet_in_child(
        tmp_path,
        f"""
        killed = []

        def kill_one(done_batches):
            if not killed:
                os.kill({workers[0].pid}, signal.SIGKILL)
                killed.append(done_batches)

        run_fleet(read_manifest({str(synthetic)!r}), {str(tmp_path / "out")!r}, scheduler={address!r}, max_logs=1,
                  on_batch=kill_one)
        assert killed
        """,
    )
    assert workers[0].wait(timeout=10) == -signal.SIGKILL
    rows = read_table(tmp_path / "out").to_pylist()
    keys = [r["log_key"] for r in rows]
    assert sorted(keys) == sorted(e.key for e in entries)  # every log, exactly once
    assert read_table(tmp_path / "out", ERRORS) is None


def test_bad_logs_land_in_the_errors_table_and_reruns_skip(tmp_path, synthetic):
    logs = tmp_path / "logs" / "truckX"
    logs.mkdir(parents=True)
    good = read_manifest(synthetic)[0].log
    shutil.copy(good, logs / "good.log")
    raw = good.read_bytes()
    (logs / "truncated.log").write_bytes(raw[: len(raw) // 2 - 7])
    lines = raw.split(b"\n")  # a log with 2 % garbage lines: summarised, untrusted, as `replay` says
    (logs / "garbled.log").write_bytes(b"\n".join(b"#garbage" if k % 50 == 7 else x for k, x in enumerate(lines)))
    (logs / "empty.log").write_bytes(b"")
    (logs / "notes.txt").write_text("not a log\n")
    (logs / "picture.log").write_bytes(bytes(range(256)) * 8)
    import gzip

    (logs / "packed.log.gz").write_bytes(gzip.compress(raw))  # was skipped without a word
    # a log of another ECU's traffic only (no engine, no gear): summarised, but not trusted, as `replay` says
    (logs / "nogear.log").write_text(
        "".join(f"({1.7e9 + 0.1 * k:.6f}) can0 18FEF100#FFFFFFFFFFFFFFFF\n" for k in range(3000))
    )
    out = tmp_path / "out"
    # the folder holding the vehicle's folder: a log lying directly in a folder given is its own vehicle
    args = [str(tmp_path / "logs"), str(logs / "notes.txt"), "--out", str(out), "--workers", "1"]
    fleet(*args)
    errors = {Path(r["log"]).name: r["reason"] for r in read_table(out, ERRORS).to_pylist()}
    assert set(errors) == {"empty.log", "notes.txt", "picture.log", "packed.log.gz"}
    assert "gzip-compressed" in errors["packed.log.gz"]
    assert "empty" in errors["empty.log"] and "unknown log suffix" in errors["notes.txt"]
    assert "binary data" in errors["picture.log"], errors["picture.log"]
    rows = {Path(r["log"]).name: r for r in read_table(out).to_pylist()}
    # a log cut mid-line (a logger unplugged): summarised without its cut last line, counted, still trusted
    assert set(rows) == {"good.log", "nogear.log", "truncated.log", "garbled.log"}
    garbled = rows["garbled.log"]
    assert not garbled["trusted"] and garbled["malformed_first_lines"] == "8, 58, 108, 158, 208"
    assert garbled["malformed_lines"] == sum(1 for k in range(len(lines)) if k % 50 == 7)
    assert "malformed lines skipped (lines 8, 58, 108, 158, 208 and" in garbled["trust_warnings"]
    cut_line = raw[: len(raw) // 2 - 7].count(b"\n") + 1
    assert rows["truncated.log"]["malformed_lines"] == 1 and rows["good.log"]["malformed_lines"] == 0
    assert rows["truncated.log"]["malformed_first_lines"] == str(cut_line) and rows["truncated.log"]["trusted"]
    assert rows["good.log"]["trusted"] and not rows["nogear.log"]["trusted"] and rows["nogear.log"]["trust_warnings"]
    report = (out / "report.md").read_text()
    assert "should not be trusted (2," in report and "| nogear.log |" in report and "| garbled.log |" in report
    assert "Logs with malformed lines skipped (2)" in report and f"| truncated.log | 1 | {cut_line} |" in report
    summary_files = sorted(str(p) for p in (out / "summary").rglob("*.parquet"))
    fleet(*args)  # a re-run: the summarised logs are not redone, the failed ones tried again, once each
    assert sorted(str(p) for p in (out / "summary").rglob("*.parquet")) == summary_files
    assert len(read_table(out).to_pylist()) == len(rows)
    assert sorted(Path(r["log"]).name for r in read_table(out, ERRORS).to_pylist()) == sorted(errors)
    assert len(list((out / "errors").glob("*.parquet"))) == 1
    # a log in the errors table is tried again once it is complete
    (logs / "truncated.log").write_bytes(raw)
    res = fleet(*args)
    assert "truncated.log" in {Path(r["log"]).name for r in read_table(out).to_pylist()}
    assert "truncated.log" not in {Path(r["log"]).name for r in read_table(out, ERRORS).to_pylist()}
    # it is now a copy of good.log: summarised twice, and said so (a copied log counted its hours twice, silently)
    assert "look like copies of each other" in res.stderr and "good.log" in res.stderr, res.stderr
    assert "| good.log, truncated.log |" in (out / "report.md").read_text()


def test_changed_moved_and_other_variant_logs_are_not_kept_stale(tmp_path, synthetic):
    """Logs are known by more than their path: a log still being written does not keep its partial summary on
    every re-run, a moved log does not count under both paths (and removing the copies helps), and a corrected
    manifest giving a vehicle another variant does not keep the rows of the first."""
    logs = tmp_path / "logs" / "truckY"
    logs.mkdir(parents=True)
    good = read_manifest(synthetic)[0].log
    lines = good.read_text().splitlines(keepends=True)
    (logs / "day1.log").write_text("".join(lines[: len(lines) // 2]))  # half written
    out = tmp_path / "out"
    args = [str(tmp_path / "logs"), "--out", str(out), "--workers", "1", "--no-report"]
    fleet(*args)
    half = read_table(out).to_pylist()[0]
    (logs / "day1.log").write_text("".join(lines))  # the whole day now
    res = fleet(*args)
    assert "0 done before, 1 summarised" in res.stdout, res.stdout
    rows = read_table(out).to_pylist()
    assert len(rows) == 1 and rows[0]["frames"] > half["frames"] and rows[0]["variant"] == "GRS905"
    assert "1 done before" in fleet(*args).stdout  # unchanged: skipped
    # moved: said, and --prune removes the old row (the new path is replayed)
    (logs / "day1.log").rename(logs / "renamed.log")
    res = fleet(*args)
    assert "no longer at their path" in res.stderr and "--prune" in res.stderr
    assert len(read_table(out).to_pylist()) == 2
    res = fleet(*args, "--prune")
    assert "prune: 1 logs no longer at their path" in res.stdout
    assert [Path(r["log"]).name for r in read_table(out).to_pylist()] == ["renamed.log"]
    # the same vehicle as another gearbox into the same output: one sentence, nothing replayed
    m = tmp_path / "m.csv"
    m.write_text(f"log,vehicle,variant\n{logs / 'renamed.log'},truckY,GRSO905\n")
    res = fleet("--manifest", str(m), "--out", str(out), "--workers", "1", check=False)
    assert res.returncode == 2 and "a vehicle is one gearbox" in res.stderr, res.stderr


def test_a_workers_service_warnings_stay_in_the_row(tmp_path, synthetic, caplog):
    """The workers' service warnings ('frame time jumped backward') stay in the log's row instead of flooding the
    console, naming no log."""
    from tools.fleet.manifest import LogEntry, log_key
    from tools.fleet.run import process_batch

    good = read_manifest(synthetic)[0].log
    lines = good.read_text().splitlines(keepends=True)
    log = tmp_path / "jumps.log"
    log.write_text("".join(lines[:4000] + lines[1000:3000]))  # the clock goes back once
    with caplog.at_level("WARNING"):
        [(kind, row)] = process_batch([LogEntry(log, "truckJ", None, None, None, log_key(log))])
    assert kind == "ok" and row["time_jumps"] >= 1
    assert not [r for r in caplog.records if "jumped" in r.getMessage()]


POISON_PRELOAD = """
import os


def dask_setup(worker):
    import tools.fleet.run as run
    real = run.process_log

    def process_log(entry, *args, **kwargs):
        if "poison" in str(entry.log):
            os._exit(1)          # a log that kills its worker (out of memory, a crash in a library)
        return real(entry, *args, **kwargs)
    run.process_log = process_log
"""


def test_a_log_that_kills_its_workers_fails_alone(tmp_path, synthetic):
    """When a log kills its workers, the batch's logs are run one by one and only the culprit fails, named; not
    the whole batch (up to 64 innocent logs, never tried again) in the errors table."""
    logs = tmp_path / "logs" / "truckP"
    logs.mkdir(parents=True)
    src = read_manifest(synthetic)
    for i, e in enumerate(src[:5]):
        shutil.copy(e.log, logs / f"good{i}.log")
    shutil.copy(src[0].log, logs / "poison.log")
    (tmp_path / "poisonpre.py").write_text(POISON_PRELOAD)
    out = tmp_path / "out"
    run_fleet_in_child(
        tmp_path,
        f"""
        import sys
        sys.path.insert(0, {str(tmp_path)!r})
        from dask.distributed import LocalCluster
        from tools.fleet.manifest import entries_from_paths
        cl = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                          preload=["poisonpre"], silence_logs=50)
        try:
            run_fleet(entries_from_paths([{str(logs)!r}]), {str(out)!r}, scheduler=cl.scheduler_address,
                      max_logs=8)
        finally:
            cl.close()
        """,
    )
    assert sorted(Path(r["log"]).name for r in read_table(out).to_pylist()) == [f"good{i}.log" for i in range(5)]
    errors = read_table(out, ERRORS).to_pylist()
    assert [Path(r["log"]).name for r in errors] == ["poison.log"] and "died" in errors[0]["reason"]


def test_an_asc_log_takes_its_date_from_its_header(tmp_path):
    """python-can reads an ASC log's frame times from its start, so the date comes from the header: else every .asc
    log is dated 'unknown' and --diagnose leaves it out without a word."""
    from tools.fleet.summary import asc_date

    p = tmp_path / "a.asc"
    p.write_text(
        "date Fri Nov 27 08:10:02.123 2026\nbase hex  timestamps absolute\ninternal events logged\n"
        "Begin Triggerblock Mon Jan 05 08:00:00.10 am 2026\n   0.100000 1  18FEF100x  Rx   d 8 FF FF\n"
    )
    assert asc_date(p) == "2026-01-05"
    p.write_text("date Mi Okt 07 08:10:02.123 2026\nbase hex  timestamps absolute\n")
    assert asc_date(p) == "2026-10-07"
    p.write_text("base hex  timestamps absolute\n")
    assert asc_date(p) is None
    # python-can's ASCWriter stamps the trigger block with the epoch: the header's own date, not 1970-01-01
    p.write_text(
        "date Sun Dec 06 20:40:01.000 2026\nbase hex  timestamps absolute\n"
        "Begin Triggerblock Thu Jan 01 00:00:00.0 1970\n   0.100000 1  18FEF100x  Rx   d 8 FF FF\n"
    )
    assert asc_date(p) == "2026-12-06"


def _error(capsys, args) -> str:
    if "--scheduler" in args:  # a Dask client: in a child process
        res = fleet(*args[1:], check=False)
        rc, err = res.returncode, res.stderr.strip()
    else:
        rc, err = main(args), capsys.readouterr().err.strip()
    assert rc == 2
    assert err.count("\n") == 0 and "error:" in err, err
    return err


def test_bad_input_is_one_sentence_and_writes_nothing(tmp_path, synthetic, capsys):
    out = tmp_path / "out"
    m = tmp_path / "m.csv"
    m.write_text("log,vehicle\nnowhere/a.log,t1\nnowhere/b.log,t2\n")
    err = _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    assert "do not exist" in err and "(line 2)" in err and "(line 3)" in err
    (tmp_path / "adir").mkdir()
    m.write_text("log,vehicle\nadir,t1\n")
    assert "names a folder where a log file belongs" in _error(
        capsys, ["fleet", "--manifest", str(m), "--out", str(out)]
    )
    logs = [e.log for e in read_manifest(synthetic)]
    # a row with more fields than the header (an unquoted comma in a path) is refused, not read without its extra
    # fields, and a row's own error says which row
    m.write_text(f"log,vehicle\n{logs[0]},t1\n{logs[1]},t2,extra\n")
    err = _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    assert "line 3 has 1 field(s) more than its header" in err and "'extra'" in err
    m.write_text(f"log,vehicle,date\n{logs[0]},t1,2026-01-05\n{logs[1]},t2,2026-02-30\n")
    assert "line 3: " in _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    m.write_text(f"log,vehicle\n{logs[0]},t1\n{logs[1]},\n")
    assert "line 3: " in _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    m.write_text(f"log,vehicle,variant\n{logs[0]},t1,GRS905\n{logs[1]},t1,GRSO905\n")
    err = _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    assert "two variants, GRS905 (line 2) and GRSO905 (line 3)" in err
    m.write_text(f"log,vehicle\n{logs[0]},t1\n{logs[1]},t1\n{logs[0]},t1\n")
    assert "listed twice (lines 2 and 4)" in _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    m.write_text(f"log,vehicle,variant\n{logs[0]},t1,GRS999\n")  # every log landed in the errors table, exit 0
    assert "vehicle t1" in _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    m.write_text(f"log,vehicle,config\n{logs[0]},t1,{tmp_path / 'absent.toml'}\n")
    assert "absent.toml" in _error(capsys, ["fleet", "--manifest", str(m), "--out", str(out)])
    port = _free_port()
    err = _error(capsys, ["fleet", str(logs[0]), "--out", str(out), "--scheduler", f"tcp://127.0.0.1:{port}"])
    assert "does not answer" in err
    err = _error(capsys, ["fleet", str(logs[0]), "--out", str(out), "--scheduler", "notaurl"])
    assert "is not a scheduler address" in err  # said 'does not answer within 10 s (ValueError)'
    assert "only --diagnose" in _error(capsys, ["fleet", str(logs[0]), "--out", str(out), "--period-days", "3"])
    assert not out.exists()
    with pytest.raises(InputError):
        read_manifest(tmp_path / "absent.csv")


def test_a_port_that_is_no_scheduler_and_a_scheduler_without_workers_are_one_sentence(tmp_path, monkeypatch):
    """--scheduler at the dashboard's port (a server that answers nothing) and a scheduler without a worker are
    each one sentence within the connect or worker timeout, not a hang."""
    import socket
    import threading

    import tools.fleet.run as R

    monkeypatch.setattr(R, "CONNECT_TIMEOUT_S", 1.0)
    monkeypatch.setattr(R, "WORKER_WAIT_S", 2.0)
    with socket.socket() as srv:  # accepts, then says nothing (as an HTTP server waits)
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        held = []
        threading.Thread(target=lambda: held.append(srv.accept()), daemon=True).start()
        with pytest.raises(InputError, match="answered as a Dask scheduler"):
            R.connect(f"tcp://127.0.0.1:{srv.getsockname()[1]}", None)
    port = _free_port()
    sched = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--no-dashboard",
        ],
        env=ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        cwd=tmp_path,
    )
    try:
        deadline = time.monotonic() + 60.0
        while R._probe_scheduler(f"tcp://127.0.0.1:{port}") is not None:
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.5)
        with pytest.raises(InputError, match="has no worker"):
            R.connect(f"tcp://127.0.0.1:{port}", None)
    finally:
        sched.kill()
        sched.wait(timeout=30)


def test_a_period_that_is_no_whole_day_is_one_sentence(tmp_path, synthetic, capsys):
    """--period-days 0.5 is refused in one sentence: it would number the periods 0, 2, 4 ... and the level rule,
    which needs consecutive periods, would never fire."""
    msg = _error(
        capsys,
        ["fleet", "--manifest", str(synthetic), "--out", str(tmp_path / "o"), "--diagnose", "--period-days", "0.5"],
    )
    assert "whole number of days" in msg and not (tmp_path / "o").exists()


def test_a_manifest_date_that_is_no_day_is_one_sentence_before_anything_runs(tmp_path, synthetic, capsys):
    """2026-02-30 has the shape YYYY-MM-DD but is no day: refused when the manifest is read, not when the fleet
    health (after the whole run) needs the date."""
    log = read_manifest(synthetic)[0].log
    m = tmp_path / "m.csv"
    m.write_text(f"log,vehicle,date\n{log},t1,2026-02-30\n")
    err = _error(capsys, ["fleet", "--manifest", str(m), "--out", str(tmp_path / "out")])
    assert "'2026-02-30' is not a day of the calendar" in err and not (tmp_path / "out").exists()


def test_a_manifest_may_leave_a_rows_optional_fields_blank(tmp_path, synthetic):
    """The date and the variant are optional: a row that leaves them blank takes the defaults (the date from the
    log), as a manifest without those columns does ('date '' is not YYYY-MM-DD' refused mixing dated rows with
    undated ones)."""
    a, b = (e.log for e in read_manifest(synthetic)[:2])
    m = tmp_path / "m.csv"
    m.write_text(f"log,vehicle,variant,date\n{a},t1,,2026-01-05\n{b},t2,,\n")
    got = read_manifest(m)
    assert [(e.vehicle, e.date, e.variant) for e in got] == [("t1", "2026-01-05", None), ("t2", None, None)]
    # a spreadsheet's export: ';' separated, names capitalised, a compact date ('has no column log or vehicle')
    m.write_text(f"Log;Vehicle;Date\n{a};t1;20260105\n{b};t2;\n")
    got = read_manifest(m)
    assert [(e.vehicle, e.date) for e in got] == [("t1", "2026-01-05"), ("t2", None)]
    m.write_text(f"Log;Vehicle;Date\n{a};t1;20261399\n")  # said as written, not as read
    with pytest.raises(InputError, match="date '20261399' is not a day of the calendar"):
        read_manifest(m)


def test_a_manifest_that_is_not_text_is_one_sentence(tmp_path, capsys):
    m = tmp_path / "m.csv"
    m.write_bytes(b"\xff\xfe\x00garbage\n")
    err = _error(capsys, ["fleet", "--manifest", str(m), "--out", str(tmp_path / "out")])
    assert "not a UTF-8 CSV" in err and not (tmp_path / "out").exists()


def test_synthetic_cold_starts_begin_at_ambient_and_the_log_says_so(tmp_path):
    """--cold-share: a key-on log starts with the oil 0-4 K above that day's ambient (what its first oil frame
    reads); a mid-shift log starts warm; the rest of the day does not depend on the share."""
    import json

    cold = synth_fleet(
        tmp_path / "cold", FleetSpec(vehicles=1, days=2, minutes=1.0, seed=4, cold_share=1.0), processes=1
    )
    warm = synth_fleet(
        tmp_path / "warm", FleetSpec(vehicles=1, days=2, minutes=1.0, seed=4, cold_share=0.0), processes=1
    )
    for manifest, is_cold in ((cold, True), (warm, False)):
        truth = json.loads((manifest.parent / "truth.json").read_text())
        for day in truth["days"]:
            assert day["cold"] is is_cold
            log = manifest.parent / day["vehicle"] / f"{day['vehicle']}_{day['date']}.log"
            table = replay_log(log, build_service(None, record=True, emit_frames=False, log_findings=False))
            oil = np.asarray(table["oil_temp_c"], dtype=float)
            first = float(oil[np.isfinite(oil)][0])
            if is_cold:
                assert 0.0 <= day["oil_start_c"] - day["ambient_c"] <= 4.0
                assert abs(first - day["oil_start_c"]) < 1.0, (first, day)
            else:
                assert first > 50.0, (first, day)
    days_cold = json.loads((cold.parent / "truth.json").read_text())["days"]
    days_warm = json.loads((warm.parent / "truth.json").read_text())["days"]
    assert [d["ambient_c"] for d in days_cold] == [d["ambient_c"] for d in days_warm]


def test_the_oil_modelled_by_request_is_not_counted_as_degraded(tmp_path, synthetic):
    """sensor.oil_mode = "model" in a vehicle's config: its oil-model-only steps are its normal mode, so the summary
    row's degraded_share stays near 0 on a clean log (it was 1.0: every step counted as degraded), as replay's
    summary."""
    from tools.fleet.run import process_log

    entry = read_manifest(synthetic)[0]
    cfg = tmp_path / "model.toml"
    cfg.write_text('[sensor]\noil_mode = "model"\n')
    status, measured = process_log(entry)
    status_m, modelled = process_log(entry._replace(config=str(cfg)))
    assert status == status_m == "ok"
    assert measured["degraded_share"] < 0.01  # the first steps, before the first inputs
    assert modelled["degraded_share"] <= measured["degraded_share"]


def test_diagnose_on_logs_too_short_to_fit_says_why_nothing_was_written(synthetic, tmp_path):
    """--diagnose on 2-minute logs prints '0 vehicle-periods fitted', writes no health folder and says why."""
    out = tmp_path / "out"
    res = fleet("--manifest", str(synthetic), "--out", str(out), "--workers", "1", "--diagnose", "--no-report")
    assert "0 vehicle-periods fitted" in res.stdout
    assert "nothing written" in res.stdout and "at least 4 min" in res.stdout, res.stdout
    assert not (out / "health").exists()


def test_a_manifest_saved_with_a_byte_order_mark_is_read(synthetic):
    """A manifest saved by a Windows editor (UTF-8 with a BOM) is read, not 'has no column log'."""
    beside = Path(synthetic).with_name("bom.csv")  # a manifest's paths are relative to it: keep it beside
    beside.write_bytes(b"\xef\xbb\xbf" + Path(synthetic).read_text().replace("\n", "\r\n").encode("utf-8"))
    try:
        assert [e.log for e in read_manifest(beside)] == [e.log for e in read_manifest(synthetic)]
    finally:
        beside.unlink()


def _simulated_day(tmp_path, name: str, start_s: float, day: str, cooler: float = 1.0) -> Path:
    """A 6-minute slice of the uphill drive from `simulate --can-log` with its frame times from ``day`` 08:00 UTC
    (--start-time), the cooler's effectiveness scaled by ``cooler``."""
    from tools.cycles.named import get_cycle
    from tools.runtable import RunTable, write_run_table

    cyc = get_cycle("uphill")
    t = np.asarray(cyc["time_s"])
    keep = (t >= start_s) & (t < start_s + 360.0)
    cols = {c: np.asarray(cyc[c])[keep] for c in cyc.columns}
    cols["time_s"] = cols["time_s"] - cols["time_s"][0]
    csv = write_run_table(RunTable(cols), tmp_path / f"{name}_cycle.csv")
    log = tmp_path / "logs" / f"{name}_{day}.log"
    log.parent.mkdir(exist_ok=True)
    assert (
        main(
            [
                "simulate",
                "--cycle",
                str(csv),
                "--initial-temp",
                "70",
                "--quiet",
                "--out",
                str(tmp_path / f"{name}.csv"),
                "--can-log",
                str(log),
                "--start-time",
                f"{day}T08:00:00Z",
                "--effect",
                f"cooler_effectiveness_scale:factor={cooler}",
            ]
        )
        == 0
    )
    return log


def test_a_flat_folder_without_a_manifest_shows_each_trucks_cooler_dated_and_no_empty_plot(tmp_path):
    """`fleet logs/` on a flat folder of simulated logs made them "N logs of 1 vehicle" with no dates,
    so --diagnose fitted nothing ("no fitted log has a date"), report_above_warning.png was empty axes, and the
    fitted coolers that separate the trucks were in periods.parquet only. Now: the dates from the logs' Unix frame
    times, the vehicle from the file name (--vehicle-from), each truck's fitted cooler in the report's table beside
    the fleet's median and spread, and a plot with nothing to show not written, the report saying why."""
    for name, start_s, cooler in (("truck1", 600.0, 1.0), ("truck2", 1200.0, 1.0), ("truck3", 1800.0, 0.4)):
        _simulated_day(tmp_path, name, start_s, "2026-01-05", cooler)
    out = tmp_path / "out"
    res = fleet(
        str(tmp_path / "logs"), "--out", str(out), "--workers", "1", "--diagnose", "--vehicle-from", r"^(truck\d+)_"
    )
    assert "vehicles: 3 read from the file names by --vehicle-from" in res.stdout, res.stdout
    assert "3 logs of 3 vehicles" in res.stdout and "3 vehicle-periods fitted" in res.stdout, res.stdout
    assert set(read_table(out).column("date").to_pylist()) == {"2026-01-05"}
    report = (out / "report.md").read_text()
    table = report.split("Cooler effectiveness scale [-]")[1].split("\n\n")[1]
    cells = {r.split(" | ")[0].strip("| "): r.split(" | ")[1] for r in table.splitlines()[2:]}
    cooler = {v: float(c.strip("*").split(" +/- ")[0]) for v, c in cells.items() if v.startswith("truck")}
    assert set(cooler) == {"truck1", "truck2", "truck3"}, table
    assert cooler["truck3"] < min(cooler["truck1"], cooler["truck2"]) - 0.3, table
    assert "below" in cells["truck3"] and "below" not in cells["truck1"] + cells["truck2"], table
    assert "fleet median" in cells and "fleet spread" in cells
    for png in ("report_peaks.png", "report_above_warning.png", "report_health.png"):
        shown = f"]({png})" in report
        assert shown == (out / png).is_file() and shown != (f"{png} not written" in report), png
    assert (out / "report_health.png").is_file()


def test_the_vehicles_of_logs_without_a_manifest_are_said(tmp_path, capsys):
    """a flat folder's logs were one vehicle, the folder's; now one vehicle per log (said), a vehicle's
    folder still names it, and --vehicle-from reads the file name (a file it does not match: one sentence)."""
    from tools.fleet.manifest import entries_and_rule

    for rel in ("flat/truck1_2026-01-05.log", "flat/truck2_2026-01-05.log", "nested/truck7/day1.log"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("(1767600000.000000) can0 0CF00400#F0C0C0A02800FFFF\n")
    entries, rule = entries_and_rule([tmp_path / "flat", tmp_path / "nested"])
    assert sorted(e.vehicle for e in entries) == ["truck1_2026-01-05", "truck2_2026-01-05", "truck7"]
    assert rule.startswith("vehicles: 3: 1 from the folders holding 1 logs; one per log for the 2 logs"), rule
    entries, rule = entries_and_rule([tmp_path / "flat"], vehicle_from=r"(?P<vehicle>truck\d+)_(?P<date>[-\d]+)\.")
    assert [(e.vehicle, e.date) for e in entries] == [("truck1", "2026-01-05"), ("truck2", "2026-01-05")]
    (tmp_path / "flat" / "spare.log").write_text("")
    msg = _error(
        capsys, ["fleet", str(tmp_path / "flat"), "--out", str(tmp_path / "o"), "--vehicle-from", r"^(truck\d+)_"]
    )
    assert "spare.log: --vehicle-from '^(truck\\d+)_' finds no vehicle in its file name spare.log" in msg, msg
    assert not (tmp_path / "o").exists()


def test_a_rerun_with_other_settings_replays_the_log_instead_of_keeping_its_row(tmp_path, synthetic):
    """A re-run into the same --out skipped every log with a row, whatever had changed: the --config that sets the
    source address its verdict advised ("1 done before, 0 summarised", the old verdict kept), a manifest renaming
    the vehicle (the row stayed under the old name), [fleet] estimates = true (no estimates, no word). A log whose
    settings differ from its row's is now replayed again, and said; rows of an earlier version, which do not record
    their settings, are kept and said."""
    good = read_manifest(synthetic)[0].log
    logs = tmp_path / "logs" / "truckY"
    logs.mkdir(parents=True)
    # the gearbox sends TRF1 (PGN 65272) from 0x21, not the default 0x03
    (logs / "day1.log").write_text(good.read_text().replace("18FEF803#", "18FEF821#"))
    out = tmp_path / "out"
    base = ["--out", str(out), "--workers", "1", "--no-report"]
    fleet(str(tmp_path / "logs"), *base)
    row = read_table(out).to_pylist()[0]
    assert row["trusted"] is False and "TRF1 = 0x21" in row["trust_warnings"], row["trust_warnings"]
    ok = tmp_path / "ok.toml"
    ok.write_text("[can.source_address]\nTRF1 = 0x21\n")
    res = fleet(str(tmp_path / "logs"), *base, "--config", str(ok))
    assert "0 done before, 1 summarised" in res.stdout and "1 of the logs summarised before" in res.stdout, res.stdout
    rows = read_table(out).to_pylist()
    assert len(rows) == 1 and rows[0]["trusted"] is True, rows[0]["trust_warnings"]
    assert "1 done before, 0 summarised" in fleet(str(tmp_path / "logs"), *base, "--config", str(ok)).stdout
    # a manifest that names the vehicle otherwise: the row moves to the new name
    m = tmp_path / "m.csv"
    m.write_text(f"log,vehicle\n{logs / 'day1.log'},truckZ\n")
    res = fleet("--manifest", str(m), *base, "--config", str(ok))
    assert "0 done before, 1 summarised" in res.stdout, res.stdout
    assert read_table(out).column("vehicle").to_pylist() == ["truckZ"]
    # estimates asked of a log summarised without them: replayed, written
    est = tmp_path / "est.toml"
    est.write_text("[can.source_address]\nTRF1 = 0x21\n[fleet]\nestimates = true\n")
    res = fleet("--manifest", str(m), *base, "--config", str(est))
    assert "0 done before, 1 summarised" in res.stdout, res.stdout
    assert [f.parent.parent.name for f in (out / "estimates").rglob("*.parquet")] == ["vehicle=truckZ"]
    assert "1 done before" in fleet("--manifest", str(m), *base, "--config", str(est)).stdout
    # a row of an earlier version (no settings recorded): kept, and said
    for f in (out / "summary").rglob("*.parquet"):
        t = pq.read_table(f)
        pq.write_table(t.drop_columns(["settings"]), f)
    res = fleet("--manifest", str(m), *base, "--config", str(est))
    assert "1 done before" in res.stdout and "summarised by an earlier version" in res.stderr, res.stderr


def test_a_fit_of_an_earlier_replay_of_its_log_is_not_used(tmp_path):
    """A log replayed again without --diagnose (its settings changed: here its vehicle renamed) kept the fit of its
    old replay, under the old vehicle: the health used it. Only a fit of the log's current row counts."""
    from tools.fleet.health import COOLER_GRID, NO_FIT_HERE, VOLUME_GRID_L, fleet_health
    from tools.fleet.store import FleetStore

    v, c = np.meshgrid(VOLUME_GRID_L, COOLER_GRID, indexing="ij")
    fit = {"sse": ((v - 12.0) ** 2 + 10 * (c - 0.8) ** 2).ravel().tolist(), "points": 100, "span_s": 600.0}
    fit |= {"cooler_grid": list(COOLER_GRID), "volume_grid_l": list(VOLUME_GRID_L), "level_pct": float("nan")}
    row = {"log": "day1.log", "log_key": "k1", "date": "2026-01-05", "start_s": 1.7e9, "duration_s": 600.0}
    store = FleetStore(tmp_path)
    store.write_batch("a", [{**row, "vehicle": "truckY", "replayed_at_s": 1.0, "_fit": dict(fit)}], [])
    assert fleet_health(tmp_path).periods == 1
    store.write_batch("b", [{**row, "vehicle": "truckZ", "replayed_at_s": 2.0}], [])  # replayed, no --diagnose
    health = fleet_health(tmp_path)
    assert health.periods == 0 and health.why_none == NO_FIT_HERE, health
    store.write_batch("c", [{**row, "vehicle": "truckZ", "replayed_at_s": 3.0, "_fit": dict(fit)}], [])
    assert [f.vehicle for f in fleet_health(tmp_path).fits] == ["truckZ"]


def test_two_trucks_logs_overlapping_in_one_vehicle_are_said(tmp_path, synthetic):
    """Two trucks' logs in one vehicle's folder, overlapping in time, were summarised and fitted as one truck
    without a word; now the run warns naming the vehicle and both logs, and the report lists them. Logs that follow
    each other (a frame repeated at the seam) and copies (reported as such) are no overlap."""
    from tools.fleet.report import overlapping_logs

    by_name = {e.log.name: e.log for e in read_manifest(synthetic)}
    folder = tmp_path / "logs" / "truckX"
    folder.mkdir(parents=True)
    # truck001's and truck002's drives of 2026-01-06 overlap by about 30 s; truck000's of 2026-01-05 overlaps neither
    for name in ("truck001_2026-01-06.log", "truck002_2026-01-06.log", "truck000_2026-01-05.log"):
        shutil.copy(by_name[name], folder / name)
    out = tmp_path / "out"
    res = fleet(str(tmp_path / "logs"), "--out", str(out), "--workers", "1")
    warned = [ln for ln in res.stderr.splitlines() if "overlap in time" in ln]
    assert len(warned) == 1 and "vehicle truckX" in warned[0], res.stderr
    assert "truck001_2026-01-06.log" in warned[0] and "truck002_2026-01-06.log" in warned[0], warned
    report = (out / "report.md").read_text()
    assert "## Logs of one vehicle that overlap in time (1 pairs)" in report, report
    assert "| truckX | truck001_2026-01-06.log | truck002_2026-01-06.log |" in report, report
    t0 = 1.7e9
    c = {
        "vehicle": ["v"] * 4,
        "log": ["a", "b", "a_copy", "c"],
        "start_s": [t0, t0 + 600.0, t0 + 600.0, t0 + 1199.5],
        "end_s": [t0 + 600.5, t0 + 1200.0, t0 + 1200.0, t0 + 1800.0],
        "frames": [10, 20, 20, 30],
    }
    assert overlapping_logs(c) == []  # seams of half a second, and a copy


def test_the_hottest_vehicles_rank_by_the_margin_to_each_parts_own_warning_limit(tmp_path, synthetic):
    """The report's "Hottest vehicles" ranked by degC across parts with different limits: a truck whose LI.teeth
    peaked at 142 degC under its 150 degC limit led one whose sun wheel (PS) sat 6 K over its 130 degC limit. Now
    the margin to each part's own warning limit (recorded in the row) ranks, and the limit is shown."""
    from tools.fleet.run import process_log
    from tools.fleet.store import FleetStore

    entry = read_manifest(synthetic)[0]
    kind, row = process_log(entry)
    assert kind == "ok" and row["warning_limit_PS_c"] == 130.0 and row["warning_limit_LI.teeth_c"] == 150.0, row
    base = {k: v for k, v in row.items() if not k.startswith(("peak_", "vehicle", "log"))}
    rows = []
    for vehicle, li_c, ps_c in (("teeth142", 142.0, 120.0), ("sun136", 120.0, 136.3), ("cool", 100.0, 100.0)):
        peaks = {k: 80.0 for k in row if k.startswith("peak_") and k.endswith("_c")}
        peaks |= {"peak_LI.teeth_c": li_c, "peak_PS_c": ps_c}
        rows.append({**base, **peaks, "vehicle": vehicle, "log": f"{vehicle}.log", "log_key": vehicle})
    FleetStore(tmp_path).write_batch("a", rows, [])
    from tools.fleet.report import write_report

    report = write_report(tmp_path).read_text()
    table = report.split("## Hottest vehicles")[1].split("\n\n")[1].splitlines()[2:]
    assert [r.split(" | ")[0].strip("| ") for r in table] == ["sun136", "teeth142", "cool"], table
    assert "| sun136 | 136.3 degC | PS | 130.0 degC | +6.3 K |" in table[0], table
    assert "| teeth142 | 142.0 degC | LI.teeth | 150.0 degC | -8.0 K |" in table[1], table


def test_the_report_lists_the_trusted_logs_with_warnings():
    """A trusted log with a warning (gear numbers of another gearbox: `replay` exits 0 and says it) stayed among the
    hottest vehicles without a word in the report; it is listed with its warning, and a fleet without any adds
    nothing."""
    from tools.fleet.report import warned_section

    c = {
        "vehicle": ["t1", "t2"],
        "log": ["/x/a.log", "/x/b.asc"],
        "trust_warnings": ["", "the gear (ETC2 SPN 523) does not follow the GRS905's ratios"],
    }
    lines: list = []
    warned_section(c, lines)
    text = "\n".join(lines)
    assert "## Logs with warnings (1, kept in the peaks and times below)" in text
    assert (
        "| t2 | b.asc | the gear (ETC2 SPN 523) does not follow the GRS905's ratios |" in text and "a.log" not in text
    )
    lines = []
    warned_section({**c, "trust_warnings": ["", ""]}, lines)
    assert lines == []


def test_a_fleet_of_logs_too_short_to_fit_says_so_not_either_reason(tmp_path):
    """Logs of 30 s summarised with --diagnose: the health said "either none was long enough ... or its logs were
    summarised by a run without --diagnose"; every log is shorter than a fit needs, so it says that, with the
    longest."""
    from tools.fleet.health import NO_FIT, NO_FIT_HERE, fleet_health
    from tools.fleet.store import FleetStore

    row = {"log": "a.log", "log_key": "k1", "date": "2026-01-05", "start_s": 1.7e9, "duration_s": 30.0}
    FleetStore(tmp_path).write_batch("a", [{**row, "vehicle": "t1", "replayed_at_s": 1.0}], [])
    assert fleet_health(tmp_path).why_none == f"{NO_FIT} (the longest log here: 0.5 min)"
    long = {**row, "vehicle": "t1", "log_key": "k2", "duration_s": 3600.0, "replayed_at_s": 2.0}
    FleetStore(tmp_path).write_batch("b", [long], [])
    assert fleet_health(tmp_path).why_none == NO_FIT_HERE
