"""Output files written all or nothing: a command that fails leaves no partial output and no temporary file.

- :func:`outputs`: ``with outputs(("--out", path1), ("--can-log", path2)) as (tmp1, tmp2):`` gives one temporary
  file per output (``None`` for an option not given), made up front in the directory of the file the output lands
  on, with the output's suffix (writers pick the format by it). When the block completes, each temporary file
  replaces its output in order; on any exception every temporary file is removed, no output is touched, and an
  ``OSError`` about one of them becomes an InputError naming the option and the user's path: ``--out x.csv: cannot
  write it (No space left on device)``.
- :func:`naming`: around a writer whose errors carry no file name (a full disk on ``write``), so that
  :func:`outputs` knows which output failed.
- :func:`write_tree`: a set of files in a directory (the C bundle), all or nothing, the directories it created
  removed again on failure.
- :func:`reserve`, :func:`publish`, :func:`discard`: the steps, for writers of a single file
  (tools.runtable.atomic_text_file).

An output that is a symbolic link is written through the link: the link stays, the file it points to is replaced.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import NamedTuple

from firmware_model.errors import InputError, VSensorError


def target_of(path) -> Path:
    """The file a write to ``path`` lands on: symbolic links followed (a missing file: where it would be)."""
    return Path(os.path.realpath(os.fspath(path)))


def temp_beside(target) -> tuple[int, Path]:
    """A new empty temporary file next to ``target`` (same directory, so that ``os.replace`` is atomic), ending in
    ``target``'s suffix: its open descriptor and path. Raises OSError."""
    target = Path(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}", dir=target.parent)
    return fd, Path(tmp)


def publish(tmp, target) -> None:
    """Make the finished temporary file ``tmp`` the file ``target``: on disk (fsync), with the usual permissions
    (0666 less the umask, not mkstemp's 0600), then renamed over ``target`` in one step."""
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, target)


def discard(tmp) -> None:
    """Remove a temporary file if it is still there."""
    try:
        os.unlink(tmp)
    except OSError:
        pass


class OutputError(InputError):
    """An output could not be written (one sentence naming the option and the user's path); ``cause``: the
    OSError."""

    def __init__(self, message: str, cause: OSError):
        super().__init__(message)
        self.cause = cause


def cannot_write(option: str | None, path, exc: OSError) -> OutputError:
    """The one sentence for an output that could not be written, naming the option and the user's path."""
    label = f"{option} {os.fspath(path)}" if option else os.fspath(path)
    return OutputError(f"{label}: cannot write it ({exc.strerror or exc})", exc)


@contextlib.contextmanager
def naming(path):
    """An OSError without a file name raised inside (a full disk while writing) gets ``path`` as its file name."""
    try:
        yield
    except OSError as exc:
        if exc.filename is None:
            exc.filename = os.fspath(path)
        raise


class Pending(NamedTuple):
    """One output of :func:`outputs`: its option, the path as the user gave it, the file it lands on, the
    temporary file it is written to, and whether that file existed before."""

    option: str
    path: str
    target: Path
    temp: Path
    existed: bool


def reserve(path, option: str | None = None) -> tuple[int, Path, Path]:
    """A temporary file for the output ``path``: its open descriptor, its path and the file it is to replace
    (:func:`temp_beside` of :func:`target_of`). InputError naming ``option`` and ``path`` when it cannot be made."""
    target = target_of(path)
    try:
        fd, tmp = temp_beside(target)
    except OSError as exc:  # named after the output, not after the temporary file it could not create
        raise cannot_write(option, path, exc) from None
    return fd, tmp, target


def _pending(option: str, path) -> Pending:
    if target_of(path).is_dir():
        raise InputError(f"{option} {os.fspath(path)} is a directory, not a file")
    fd, tmp, target = reserve(path, option)
    os.close(fd)
    return Pending(option, os.fspath(path), target, tmp, target.exists())


def _publish_all(pending: list[Pending]) -> None:
    """Each temporary file onto its output, in order; when one cannot be, the outputs this run made are removed
    again (outputs that existed before are already replaced: a rename in one directory rarely fails)."""
    for k, p in enumerate(pending):
        try:
            publish(p.temp, p.target)
        except OSError:
            for done in pending[:k]:
                if not done.existed:
                    discard(done.target)
            raise


def _mentions(exc: OSError, tmp: Path) -> bool:
    """Is the error about ``tmp`` (or a writer's own temporary file next to it, named after it)?"""
    names = [
        Path(os.fsdecode(f)).name for f in (exc.filename, exc.filename2) if isinstance(f, (str, bytes, os.PathLike))
    ]
    return any(tmp.name in n for n in names)


def _unmask(message: str, pending: list[Pending]) -> str:
    """A message naming a temporary file names the user's path instead."""
    for p in pending:
        message = message.replace(os.fspath(p.temp), p.path).replace(p.temp.name, p.path)
    return message


@contextlib.contextmanager
def outputs(*named):
    """``named``: (option, path or None) pairs. Yields the temporary paths (str; None for a path not given) to write
    instead; see the module doc."""
    pending: list[Pending] = []
    try:
        temps = []
        for option, path in named:
            if path:
                pending.append(_pending(option, path))
            temps.append(os.fspath(pending[-1].temp) if path else None)
        yield temps
        _publish_all(pending)
    except OSError as exc:
        for p in pending:
            discard(p.temp)
        culprit = next((p for p in pending if _mentions(exc, p.temp)), None)
        if culprit is None:
            raise
        raise cannot_write(culprit.option, culprit.path, exc) from None
    except VSensorError as exc:
        for p in pending:
            discard(p.temp)
        if len(exc.args) == 1 and isinstance(exc.args[0], str):
            exc.args = (_unmask(exc.args[0], pending),)
        raise
    except BaseException:
        for p in pending:
            discard(p.temp)
        raise


def write_tree(out_dir, files: dict, option: str = "--out") -> Path:
    """Write ``files`` ({relative path: text or bytes}) under ``out_dir``, all or nothing: on failure nothing this
    run wrote is left, the directories it created are removed again and files that were there before are
    untouched. Text is written as ``Path.write_text`` writes it. Errors name ``option`` and the user's path."""
    out = Path(out_dir)
    made = []  # directories this run creates, outermost first
    for rel in sorted({str(Path(r).parent) for r in files}):
        for d in reversed([Path(out, rel), *Path(out, rel).parents]):
            if not d.exists() and d not in made:
                made.append(d)
    try:
        for d in made:
            d.mkdir()
        names = [(option, os.path.join(os.fspath(out_dir), rel)) for rel in files]
        with outputs(*names) as temps:
            for tmp, content in zip(temps, files.values()):
                with naming(tmp):
                    if isinstance(content, bytes):
                        Path(tmp).write_bytes(content)
                    else:
                        Path(tmp).write_text(content)
    except BaseException as exc:
        for d in reversed(made):
            with contextlib.suppress(OSError):
                d.rmdir()
        if isinstance(exc, OSError) and exc.filename and Path(os.fsdecode(exc.filename)) in made:
            raise OutputError(
                f"{option} {os.fspath(out_dir)}: cannot make the directory {exc.filename} ({exc.strerror or exc})", exc
            ) from None
        raise
    return out
