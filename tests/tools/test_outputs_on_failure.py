"""A command that fails leaves nothing half-written (tools/outputs.py): no partial output, no temporary file, the
files that were there before untouched; its message is one sentence naming the option and the user's path. Writes
are made to fail with monkeypatch (a full disk: OSError ENOSPC), so the tests run anywhere."""

from __future__ import annotations

import errno
import os
import pathlib
import zipfile

import pytest

from firmware_model.errors import InputError
from tools.cli import main
from tools.outputs import outputs

STEADY = "steady:gear=4L,rpm=1300,nm=2000,s=20"
ENOSPC = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def snapshot(d) -> dict:
    """Every file and directory under ``d`` (hidden ones too) with its bytes; symbolic links as their target."""
    out = {}
    for p in sorted(pathlib.Path(d).rglob("*")):
        rel = p.relative_to(d).as_posix()
        out[rel] = ("->", os.readlink(p)) if p.is_symlink() else (None if p.is_dir() else p.read_bytes())
    return out


def full_disk(path, data=b"partial"):
    """What a writer does on a full disk: part of the file, then ENOSPC (an OSError without a file name)."""
    pathlib.Path(path).write_bytes(data)
    raise OSError(ENOSPC.errno, ENOSPC.strerror)


def one_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    return err


@pytest.fixture
def work(tmp_path, monkeypatch):
    """A directory holding a file from before (which must stay as it is), as the current directory."""
    d = tmp_path / "work"
    d.mkdir()
    (d / "keep.txt").write_text("from before\n")
    monkeypatch.chdir(d)
    return d


@pytest.fixture(scope="module")
def can_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim")
    assert (
        main(["simulate", "--cycle", STEADY, "--out", str(d / "run.csv"), "--can-log", str(d / "run.log"), "--quiet"])
        == 0
    )
    return d / "run.log"


# ---------------------------------------------------------------- simulate


def test_simulate_can_log_full_disk_leaves_no_run_table(work, monkeypatch, capsys):
    import tools.can.logsynth as logsynth

    monkeypatch.setattr(logsynth, "write_can_log", lambda a, b, path, *args, **kw: full_disk(path))
    before = snapshot(work)
    assert main(["simulate", "--cycle", STEADY, "--out", "s.csv", "--can-log", "s.log", "--quiet"]) == 2
    assert one_error(capsys) == (
        "gearbox-vsensor simulate: error: --can-log s.log: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_simulate_bad_can_config_found_when_the_log_is_written_leaves_nothing(work, capsys):
    (work / "bad.toml").write_text("[can]\nretarder_reference_torque_nm = -5\n")
    before = snapshot(work)
    assert (
        main(["simulate", "--cycle", STEADY, "--config", "bad.toml", "--out", "s.csv", "--can-log", "s.log", "--quiet"])
        == 2
    )
    assert "error:" in one_error(capsys)
    assert snapshot(work) == before


def test_simulate_plot_full_disk_keeps_no_csv_and_the_old_one_untouched(work, monkeypatch, capsys):
    import tools.plots

    (work / "s.csv").write_text("old table\n")
    monkeypatch.setattr(tools.plots, "save_figure", lambda fig, path, **kw: full_disk(path))
    before = snapshot(work)
    assert main(["simulate", "--cycle", STEADY, "--out", "s.csv", "--plot", "p.png", "--quiet"]) == 2
    assert one_error(capsys) == (
        "gearbox-vsensor simulate: error: --plot p.png: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_simulate_unwritable_directory_fails_before_the_run_naming_the_users_path(work, monkeypatch, capsys):
    import tools.outputs

    real = tools.outputs.tempfile.mkstemp
    ro = work / "ro"
    ro.mkdir()

    def denied(*a, dir=None, **kw):
        if pathlib.Path(dir) == ro:
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.path.join(dir, ".s.log.x.tmp.log"))
        return real(*a, dir=dir, **kw)

    monkeypatch.setattr(tools.outputs.tempfile, "mkstemp", denied)
    before = snapshot(work)
    assert main(["simulate", "--cycle", STEADY, "--out", "s.csv", "--can-log", "ro/s.log", "--quiet"]) == 2
    err = one_error(capsys)
    assert err == f"gearbox-vsensor simulate: error: --can-log ro/s.log: cannot write it ({os.strerror(errno.EACCES)})"
    assert snapshot(work) == before


def test_simulate_can_log_suffix_is_checked_up_front(work, capsys):
    before = snapshot(work)
    assert main(["simulate", "--cycle", STEADY, "--out", "s.csv", "--can-log", "s.txt", "--quiet"]) == 2
    assert "--can-log s.txt: a CAN log is written as .log" in one_error(capsys)
    assert snapshot(work) == before


def test_simulate_writes_through_a_symlink(work, tmp_path):
    assert main(["simulate", "--cycle", STEADY, "--out", str(tmp_path / "plain.csv"), "--quiet"]) == 0
    os.symlink("target.csv", work / "link.csv")  # dangling: the run creates the file it points to
    assert main(["simulate", "--cycle", STEADY, "--out", "link.csv", "--quiet"]) == 0
    assert (work / "link.csv").is_symlink() and os.readlink(work / "link.csv") == "target.csv"
    assert (work / "target.csv").read_bytes() == (tmp_path / "plain.csv").read_bytes()
    assert sorted(p.name for p in work.iterdir()) == ["keep.txt", "link.csv", "target.csv"]


# ---------------------------------------------------------------- replay


def test_replay_bad_log_leaves_no_frames_out(work, capsys):
    (work / "garbage.log").write_text("(0.0) can0 18FEF100#0011223344556677\nhello\n")
    before = snapshot(work)
    assert main(["replay", "garbage.log", "--out", "g.csv", "--frames-out", "gf.log", "--quiet"]) == 2
    err = one_error(capsys)  # no step left once the malformed line 2 is skipped: said with the line
    assert "garbage.log: no sensor step" in err and "(1 malformed line skipped (line 2))" in err
    assert snapshot(work) == before


def test_replay_unwritable_out_leaves_no_frames_out(work, can_log, monkeypatch, capsys):
    import tools.runtable

    monkeypatch.setattr(tools.runtable, "write_run_table", lambda table, path, *a, **kw: full_disk(path))
    before = snapshot(work)
    assert main(["replay", str(can_log), "--out", "r.csv", "--frames-out", "rf.log", "--quiet"]) == 2
    assert one_error(capsys) == (
        "gearbox-vsensor replay: error: --out r.csv: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_replay_log_plot_full_disk_keeps_no_csv(work, can_log, monkeypatch, capsys):
    import tools.plots

    monkeypatch.setattr(tools.plots, "save_figure", lambda fig, path, **kw: full_disk(path))
    before = snapshot(work)
    assert (
        main(
            [
                "replay",
                str(can_log),
                "--out",
                "r.csv",
                "--frames-out",
                "rf.log",
                "--plot",
                "rp.png",
                "--quiet",
                "--allow-untrusted",
            ]
        )
        == 2
    )
    assert one_error(capsys) == (
        "gearbox-vsensor replay: error: --plot rp.png: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_replay_table_plot_full_disk_keeps_no_csv(work, can_log, monkeypatch, capsys):
    import tools.plots

    (work / "in.csv").write_bytes(can_log.with_name("run.csv").read_bytes())
    monkeypatch.setattr(tools.plots, "save_figure", lambda fig, path, **kw: full_disk(path))
    before = snapshot(work)
    assert main(["replay", "in.csv", "--out", "r.csv", "--plot", "rp", "--quiet", "--allow-untrusted"]) == 2
    assert one_error(capsys) == (
        "gearbox-vsensor replay: error: --plot rp.png: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_replay_writes_through_symlinks(work, can_log, capsys):
    os.symlink("t.csv", work / "r.csv")
    os.symlink("tf.log", work / "rf.log")
    assert main(["replay", str(can_log), "--out", "r.csv", "--frames-out", "rf.log", "--allow-untrusted"]) in (0, 3)
    assert "-> r.csv" in capsys.readouterr().out
    assert (work / "r.csv").is_symlink() and (work / "rf.log").is_symlink()
    assert (work / "t.csv").stat().st_size > 1000 and (work / "tf.log").stat().st_size > 1000
    assert not [p for p in work.iterdir() if p.name.startswith(".")]


# ---------------------------------------------------------------- export-c, export-fmu


def failing_write_text(monkeypatch, name):
    real = pathlib.Path.write_text

    def write_text(self, data, *a, **kw):
        if name in self.name:
            full_disk(self, data[: len(data) // 2].encode())
        return real(self, data, *a, **kw)

    monkeypatch.setattr(pathlib.Path, "write_text", write_text)


def test_export_c_full_disk_removes_what_it_wrote_and_the_directory_it_made(work, monkeypatch, capsys):
    failing_write_text(monkeypatch, "gvs_tables.c")
    before = snapshot(work)
    assert main(["export-c", "--out", "new/cb", "--quiet"]) == 2
    assert one_error(capsys) == (
        "gearbox-vsensor export-c: error: --out new/cb/gvs_tables.c: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_export_c_full_disk_keeps_the_files_that_were_there(work, monkeypatch, capsys):
    (work / "cb").mkdir()
    (work / "cb" / "Makefile").write_text("an older bundle's Makefile\n")
    (work / "cb" / "gvs_kernel.h").write_text("/* gearbox-vsensor onboard step: an older bundle's header */\n")
    (work / "cb" / "notes.txt").write_text("the user's\n")
    failing_write_text(monkeypatch, "gvs_tables.c")
    before = snapshot(work)
    assert main(["export-c", "--out", "cb", "--quiet"]) == 2
    assert "--out cb/gvs_tables.c: cannot write it (No space left on device)" in one_error(capsys)
    assert snapshot(work) == before


@pytest.fixture
def fake_fmu_build(monkeypatch, tmp_path):
    """export-fmu without FMPy's headers, a C compiler or the build's 15 s: a small FMU tree."""
    import tools.export.fmu as fmu

    def build(tmp, *a, **kw):
        (tmp / "fmu").mkdir()
        (tmp / "fmu" / "modelDescription.xml").write_text("<fmiModelDescription/>\n")
        return tmp / "fmu"

    monkeypatch.setattr(fmu, "_fmi_headers", lambda: str(tmp_path))
    monkeypatch.setattr(fmu, "compiler", lambda: "cc")
    monkeypatch.setattr(fmu, "_build", build)


def test_export_fmu_full_disk_leaves_no_temporary_file(work, fake_fmu_build, monkeypatch, capsys):
    monkeypatch.setattr(zipfile.ZipFile, "write", lambda self, *a, **kw: full_disk(self.filename))
    before = snapshot(work)
    assert main(["export-fmu", "--out", "x.fmu", "--quiet"]) == 2
    assert one_error(capsys) == (
        "gearbox-vsensor export-fmu: error: --out x.fmu: cannot write it (No space left on device)"
    )
    assert snapshot(work) == before


def test_export_fmu_out_a_directory_is_refused_up_front(work, fake_fmu_build, capsys):
    (work / "d.fmu").mkdir()
    before = snapshot(work)
    assert main(["export-fmu", "--out", "d.fmu", "--quiet"]) == 2
    assert one_error(capsys) == "gearbox-vsensor export-fmu: error: --out d.fmu is a directory, not a file"
    assert snapshot(work) == before


def test_export_fmu_writes_through_a_symlink(work, fake_fmu_build):
    os.symlink("real.fmu", work / "x.fmu")
    assert main(["export-fmu", "--out", "x.fmu", "--quiet"]) == 0
    assert (work / "x.fmu").is_symlink()
    assert zipfile.ZipFile(work / "real.fmu").namelist() == ["modelDescription.xml"]
    assert sorted(p.name for p in work.iterdir()) == ["keep.txt", "real.fmu", "x.fmu"]


# ---------------------------------------------------------------- tools.outputs itself


def test_outputs_commits_all_or_removes_all(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.log"
    with outputs(("--out", a), ("--frames-out", None), ("--can-log", b)) as (ta, tn, tb):
        assert tn is None and ta.endswith(".csv") and tb.endswith(".log")
        assert pathlib.Path(ta).parent == tmp_path and not a.exists()
        pathlib.Path(ta).write_text("A")
        pathlib.Path(tb).write_text("B")
    assert a.read_text() == "A" and b.read_text() == "B"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.log"]
    with pytest.raises(InputError, match=r"^--can-log .*b\.log: cannot write it \(No space left on device\)$"):
        with outputs(("--out", a), ("--can-log", b)) as (ta, tb):
            pathlib.Path(ta).write_text("new A")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), tb)
    assert a.read_text() == "A" and b.read_text() == "B"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.log"]


def test_outputs_rolls_back_new_outputs_when_a_rename_fails(tmp_path, monkeypatch):
    a, b = tmp_path / "a.csv", tmp_path / "b.log"
    real = os.replace

    def replace(src, dst):
        if pathlib.Path(dst) == b:
            raise OSError(errno.EIO, os.strerror(errno.EIO), src, dst)
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(InputError, match=r"^--can-log .*b\.log: cannot write it"):
        with outputs(("--out", a), ("--can-log", b)) as (ta, tb):
            pathlib.Path(ta).write_text("A")
            pathlib.Path(tb).write_text("B")
    assert list(tmp_path.iterdir()) == []


def test_outputs_error_naming_a_temporary_file_names_the_users_path(tmp_path):
    with pytest.raises(InputError) as info:
        with outputs(("--out", tmp_path / "a.csv")) as (ta,):
            raise InputError(f"{ta}: cannot write a run table without columns")
    assert str(info.value) == f"{tmp_path / 'a.csv'}: cannot write a run table without columns"
    assert list(tmp_path.iterdir()) == []


def test_other_errors_pass_unchanged_and_clean_up(tmp_path):
    with pytest.raises(OSError, match="input.log"):
        with outputs(("--out", tmp_path / "a.csv")):
            raise OSError(errno.EIO, os.strerror(errno.EIO), "input.log")
    with pytest.raises(KeyboardInterrupt):
        with outputs(("--out", tmp_path / "a.csv")):
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
