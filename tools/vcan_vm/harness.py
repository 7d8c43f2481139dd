"""Run shell scripts inside a small QEMU VM whose Debian kernel has real SocketCAN (vcan).

The development and CI machines run a kernel without CAN support, so ``vcan0`` cannot be
created there.  This module boots Debian's ``linux-image-amd64`` kernel under QEMU (TCG, no
KVM) with a tiny busybox initramfs, loads the virtio/9p/CAN modules, mounts the *host's whole
root* read-only over 9p, chroots into it and runs a ``/bin/sh`` script there with ``vcan0`` up.
Every host program (can-utils, ``ip``, the host's Python with the repo importable) therefore
runs inside the VM against a real Linux vcan0.

Inside the script:

* ``$VM_SHARE`` is a writable directory shared with the host (9p).  Its path inside the VM is
  the same absolute path as on the host, and it is the script's working directory.  Files
  written there are on the host when :func:`run_in_vm` returns.
* ``$VM_PYTHON`` is the host interpreter's absolute path (``sys.executable``; symlinks kept so
  a venv stays a venv); its directory is first on ``PATH`` (the chroot's PATH differs).
* ``$VM_REPO`` is the repo root; it is also on ``PYTHONPATH`` so ``import firmware_model`` and
  ``python -m tools.cli`` work from any working directory (an editable install works too: the
  paths are the same inside).
* ``/run``, ``/dev`` (devtmpfs, with ``/dev/pts`` and ``/dev/shm``), ``/proc`` and ``/sys`` are
  the VM's own and writable; ``/tmp`` shows the host's /tmp with the VM's writes kept in RAM
  (overlayfs); everything else is the host's root, read-only (9p, cached: host edits made while
  a VM runs may not be seen by it).
* Background jobs (``&``, ``wait``, ``kill``) work; whatever is still running when the script
  ends is killed by the power-off.

Standard library only.  CLI: ``python -m tools.vcan_vm.harness check|install|run``.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import gzip
import hashlib
import io
import lzma
import os
import re
import selectors
import shlex
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TextIO

__all__ = [
    "VMUnavailable",
    "VMError",
    "VMTimeout",
    "VMBootHang",
    "Assets",
    "VMResult",
    "vm_prerequisites",
    "ensure_vm_assets",
    "run_in_vm",
    "APT_PACKAGES",
    "INSTALL_HINT",
]

#: Debian packages the harness needs on the host (they are also what runs inside the VM).
APT_PACKAGES = ("qemu-system-x86", "linux-image-amd64", "busybox-static", "can-utils", "kmod", "iproute2")
INSTALL_HINT = "run `python -m tools.vcan_vm install` (apt-get, needs root)"

#: Modules loaded by the initramfs, in order.  Missing ones (built in) are skipped.
MODULES = (
    "virtio_ring",
    "virtio",
    "virtio_pci_modern_dev",
    "virtio_pci_legacy_dev",
    "virtio_pci",
    "netfs",
    "fscache",
    "9pnet",
    "9pnet_virtio",
    "9p",
    "can",
    "can-raw",
    "can-dev",
    "vcan",
    "overlay",  # optional: keeps the host's /tmp visible under the VM's writable /tmp
    "sch_tbf",  # optional: a token-bucket qdisc on vcan0 makes its transmit queue overflow (ENOBUFS) in a test
)
#: Modules without which the VM cannot do its job (the rest may be built in or optional).
REQUIRED_MODULES = ("9pnet_virtio", "9p", "can", "can-raw", "vcan")

SENTINEL_BEGIN = "VM-SCRIPT-BEGIN"
SENTINEL_EXIT = "VM-EXIT-CODE="
SENTINEL_TIMEOUT = "VM-SCRIPT-TIMEOUT"
SENTINEL_INIT_FAIL = "VM-INIT-FAILED:"
#: The initramfs prints this first: the kernel has booted.  Its absence within ``boot_timeout_s`` is a boot hang.
INIT_MARKER = "vcan-vm: init started"

QEMU = "qemu-system-x86_64"
CAN_TOOLS = ("candump", "cangen", "canplayer", "cansend")
MIN_FREE_BYTES_INSTALL = 1_500_000_000
APT_TIMEOUT_S = 1200
# Seconds reserved for boot and power-off: the in-VM watchdog kills the script this much
# before the host-side deadline so that its console output still comes back.
_BOOT_MARGIN_S = 20.0
_INITRAMFS_FORMAT = 4  # bump when the initramfs layout changes (part of the cache key)

REPO_ROOT = Path(__file__).resolve().parents[2]


class VMUnavailable(Exception):
    """The VM cannot be run here: something is missing.  ``reason`` names it and how to get it."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


class VMError(RuntimeError):
    """The VM ran but did not deliver the script's exit status (boot or init failure)."""

    def __init__(self, message: str, output: str = ""):
        super().__init__(message)
        self.output = output


class VMTimeout(VMError, TimeoutError):
    """The script (or the boot) did not finish within ``timeout_s``; QEMU was killed."""


class VMBootHang(VMTimeout):
    """The kernel did not start the init within ``boot_timeout_s``; QEMU was killed.

    Under TCG the kernel very rarely hangs before its init (seen once in CI: no console output after the BIOS for
    900 s, while every other boot of the same run took ~6 s).  :func:`run_in_vm` retries such a boot.
    """


@dataclasses.dataclass(frozen=True)
class Assets:
    kernel: Path  # /boot/vmlinuz-<version>
    kernel_version: str
    initramfs: Path  # cached cpio.gz
    qemu: Path
    modules: tuple[str, ...]  # modules packed into the initramfs, in load order


@dataclasses.dataclass
class VMResult:
    returncode: int
    output: str  # full serial console output (kernel + init + script), \r stripped
    share_dir: Path
    boot_s: float | None = None  # QEMU start -> script start, host wall clock
    total_s: float | None = None  # QEMU start -> QEMU exit
    boot_attempts: int = 1  # 2 or more: the first boot(s) hung before the init and were retried
    smp: int = 2  # the CPUs of the boot that ran the script (1 when the last retry ran it)

    @property
    def script_output(self) -> str:
        """What the script printed (stdout and stderr), between the init's sentinels."""
        out = self.output
        start = out.find(SENTINEL_BEGIN + "\n")
        start = 0 if start < 0 else start + len(SENTINEL_BEGIN) + 1
        end = out.rfind(SENTINEL_EXIT)
        end = len(out) if end < start else end
        return out[start:end]


# --------------------------------------------------------------------------- prerequisites


def _version_key(version: str) -> list:
    return [(0, int(p), "") if p.isdigit() else (1, 0, p) for p in re.split(r"[.\-+~]", version)]


@functools.lru_cache(maxsize=8)
def _module_index(kver: str) -> dict[str, Path]:
    """Module name (dashes as underscores) -> file under /lib/modules/<kver>/kernel."""
    index: dict[str, Path] = {}
    base = Path("/lib/modules") / kver / "kernel"
    for dirpath, _dirs, files in os.walk(base):
        for fname in sorted(files):
            stem, sep, suffix = fname.partition(".ko")
            if sep and suffix in ("", ".xz", ".gz", ".zst"):
                index.setdefault(stem.replace("-", "_"), Path(dirpath) / fname)
    return index


def _module_file(kver: str, name: str) -> Path | None:
    """The module's file under /lib/modules/<kver>, any compression; None when absent."""
    path = _module_index(kver).get(name.replace("-", "_"))
    return path if path is not None and path.is_file() else None


def _module_builtin(kver: str, name: str) -> bool:
    path = Path("/lib/modules") / kver / "modules.builtin"
    try:
        text = path.read_text()
    except OSError:
        return False
    names = {name, name.replace("-", "_"), name.replace("_", "-")}
    for line in text.splitlines():
        stem = line.rsplit("/", 1)[-1]
        stem = stem.split(".ko", 1)[0]
        if stem in names:
            return True
    return False


def _find_kernel() -> tuple[Path, str] | None:
    """Newest /boot/vmlinuz-* whose /lib/modules has vcan (module or built in)."""
    found = []
    for kernel in Path("/boot").glob("vmlinuz-*"):
        kver = kernel.name[len("vmlinuz-") :]
        if _module_file(kver, "vcan") or _module_builtin(kver, "vcan"):
            found.append((kernel, kver))
    if not found:
        return None
    return max(found, key=lambda kv: _version_key(kv[1]))


def _is_static_elf(path: Path) -> bool:
    """True when ``path`` is an ELF executable without a PT_INTERP (dynamic loader) segment."""
    try:
        with open(path, "rb") as fh:
            ident = fh.read(64)
            if len(ident) < 64 or ident[:4] != b"\x7fELF" or ident[4] != 2:
                return False
            end = "<" if ident[5] == 1 else ">"
            (phoff,) = struct.unpack(end + "Q", ident[32:40])
            phentsize, phnum = struct.unpack(end + "HH", ident[54:58])
            fh.seek(phoff)
            table = fh.read(phentsize * phnum)
    except OSError:
        return False
    for i in range(phnum):
        (p_type,) = struct.unpack(end + "I", table[i * phentsize : i * phentsize + 4])
        if p_type == 3:  # PT_INTERP
            return False
    return True


def _find_busybox() -> Path | None:
    for cand in ("/bin/busybox", "/usr/bin/busybox", shutil.which("busybox") or ""):
        if cand and Path(cand).is_file() and _is_static_elf(Path(cand)):
            return Path(cand)
    return None


def _host_python() -> Path:
    """The running interpreter's absolute path.

    Made absolute but deliberately not symlink-resolved: a venv's ``bin/python`` is a symlink
    and resolving it would lose the venv (and its site-packages).  The whole host root is
    shared, so the same path, symlinks included, works inside the chroot.
    """
    exe = sys.executable or shutil.which("python3") or "/usr/bin/python3"
    return Path(os.path.abspath(exe))


def vm_prerequisites() -> list[str]:
    """What is missing on this host to run the VM; an empty list means ready.

    Each entry names the missing piece and the Debian package that provides it.
    """
    missing = []
    if not shutil.which(QEMU):
        missing.append(f"{QEMU} (Debian package qemu-system-x86)")
    kernel = _find_kernel()
    if kernel is None:
        missing.append("a /boot/vmlinuz-* kernel with the vcan module (Debian package linux-image-amd64)")
    else:
        kpath, kver = kernel
        if not os.access(kpath, os.R_OK):
            missing.append(f"read access to {kpath} (run as root, or make it readable)")
        for name in REQUIRED_MODULES:
            if not (_module_file(kver, name) or _module_builtin(kver, name)):
                missing.append(f"kernel module {name} for {kver} (Debian package linux-image-{kver})")
    if _find_busybox() is None:
        missing.append("a statically linked busybox (Debian package busybox-static)")
    for tool in CAN_TOOLS:
        if not shutil.which(tool, path=_CHROOT_PATH):
            missing.append(f"{tool} (Debian package can-utils)")
            break
    if not shutil.which("ip", path=_CHROOT_PATH):
        missing.append("ip (Debian package iproute2)")
    return missing


# --------------------------------------------------------------------------- install

_apt_updated = False


def _apt(args: list[str]) -> subprocess.CompletedProcess:
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive", INITRD="No")
    cmd = ["apt-get", *args]
    if os.geteuid() != 0:
        if not shutil.which("sudo"):
            raise VMUnavailable(
                f"installing needs root: run `sudo {shlex.join([sys.executable, '-m', 'tools.vcan_vm', 'install'])}`"
            )
        cmd = ["sudo", "-n", "env", "DEBIAN_FRONTEND=noninteractive", "INITRD=No", *cmd]
    try:
        return subprocess.run(
            cmd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            timeout=APT_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired as exc:
        raise VMUnavailable(f"`{' '.join(cmd)}` did not finish within {APT_TIMEOUT_S} s") from exc
    except FileNotFoundError as exc:
        raise VMUnavailable("apt-get not found: install " + " ".join(APT_PACKAGES) + " by hand") from exc


def _install_packages(log: TextIO | None) -> None:
    global _apt_updated
    if shutil.which("apt-get") is None:
        raise VMUnavailable("apt-get not found: install " + " ".join(APT_PACKAGES) + " by hand")
    free = shutil.disk_usage("/").free
    if free < MIN_FREE_BYTES_INSTALL:
        raise VMUnavailable(
            f"only {free / 1e9:.1f} GB free on /; installing {' '.join(APT_PACKAGES)} needs about 1.5 GB"
        )
    if not _apt_updated:
        if log:
            print("vcan_vm: apt-get update", file=log, flush=True)
        res = _apt(["update", "-q"])
        if res.returncode != 0:
            raise VMUnavailable("apt-get update failed:\n" + res.stdout[-2000:])
        _apt_updated = True
    if log:
        print("vcan_vm: apt-get install -y --no-install-recommends " + " ".join(APT_PACKAGES), file=log, flush=True)
    res = _apt(["install", "-y", "--no-install-recommends", *APT_PACKAGES])
    _module_index.cache_clear()
    if res.returncode != 0:
        # Kernel post-install hooks (update-initramfs, grub, ...) may fail in a container; what the
        # harness needs is /boot/vmlinuz-* and /lib/modules, so judge by what is on disk.
        still = vm_prerequisites()
        if still:
            raise VMUnavailable(
                "apt-get install failed and left missing: " + "; ".join(still) + "\n" + res.stdout[-2000:]
            )
        if log:
            print(
                "vcan_vm: apt-get install exited with status "
                f"{res.returncode} (post-install hooks); the files needed are present, continuing",
                file=log,
                flush=True,
            )


def _cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "gearbox-vsensor" / "vm"


def ensure_vm_assets(install: bool = False, log: TextIO | None = None) -> Assets:
    """Kernel, initramfs (built and cached when needed) and QEMU, ready to boot.

    With ``install=True`` missing Debian packages are installed with apt-get first.
    Raises :class:`VMUnavailable` naming what is missing otherwise.
    """
    missing = vm_prerequisites()
    if missing and install:
        _install_packages(log)
        missing = vm_prerequisites()
    if missing:
        raise VMUnavailable("missing: " + "; ".join(missing) + f" -- {INSTALL_HINT}")
    kernel, kver = _find_kernel()  # type: ignore[misc]
    busybox = _find_busybox()
    assert busybox is not None
    modules = [(name, _module_file(kver, name)) for name in MODULES]
    modules = [(name, path) for name, path in modules if path is not None]
    initramfs = _ensure_initramfs(kver, busybox, modules, log)
    return Assets(
        kernel=kernel,
        kernel_version=kver,
        initramfs=initramfs,
        qemu=Path(shutil.which(QEMU)),  # type: ignore[arg-type]
        modules=tuple(name for name, _ in modules),
    )


# --------------------------------------------------------------------------- initramfs

_INIT = r"""#!/bin/busybox sh
# /init of the gearbox-vsensor vcan VM (generated by tools/vcan_vm/harness.py).
export PATH=/bin
fail() { echo "@INIT_FAIL@ $*"; echo "@EXIT@255"; sync; poweroff -f; sleep 5; exit 1; }
mount -t proc proc /proc
echo 3 > /proc/sys/kernel/printk  # the kernel's boot log went to the console; from here on critical and worse
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
read -r up _ < /proc/uptime; echo "vcan-vm: init started at ${up} s uptime"
while read -r m; do
  [ -n "$m" ] || continue
  out=$(insmod "/lib/modules/$m.ko" 2>&1) || case "$out" in
    *"exists"*) ;;
    *) echo "vcan-vm: insmod $m: $out" ;;
  esac
done < /modules.order
R=/newroot
mkdir -p $R /ctl
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 ctl /ctl || fail "mount control dir (9p)"
. /ctl/params || fail "read /ctl/params"
mount -t 9p -o "$VM_ROOT_9P_OPTS" hostroot $R || fail "mount host root (9p)"
mount -t proc proc $R/proc || fail "mount /proc"
mount -t sysfs sysfs $R/sys || fail "mount /sys"
mount -t devtmpfs devtmpfs $R/dev || fail "mount /dev"
mkdir -p $R/dev/pts $R/dev/shm
mount -t devpts devpts $R/dev/pts
mount -t tmpfs -o mode=1777 shm $R/dev/shm
# /tmp: the host's /tmp read-only below, the VM's writes in RAM above (overlayfs), so host paths
# under /tmp (a venv, a checkout, pytest's tmp_path) stay visible; plain tmpfs if overlay fails.
mkdir -p /vmtmp && mount -t tmpfs -o mode=755 tmpfs /vmtmp
mkdir -p /vmtmp/upper /vmtmp/work && chmod 1777 /vmtmp/upper
mount -t overlay -o lowerdir=$R/tmp,upperdir=/vmtmp/upper,workdir=/vmtmp/work overlay $R/tmp 2>/dev/null || {
  echo "vcan-vm: overlay on /tmp failed, host /tmp hidden by a tmpfs"
  mount -t tmpfs -o mode=1777 tmpfs $R/tmp || fail "mount /tmp"
}
mount -t tmpfs -o mode=755 tmpfs $R/run || fail "mount /run"
mkdir -p "$R$VM_SHARE" 2>/dev/null
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 share "$R$VM_SHARE" || fail "mount share at $VM_SHARE"
mkdir -p $R/run/vcan-vm
cp /ctl/run.sh /ctl/script.sh $R/run/vcan-vm/ || fail "copy script"
[ ! -d /ctl/pyhide ] || cp -r /ctl/pyhide $R/run/vcan-vm/ || fail "copy the hidden-module stubs"
ip link set lo up
chroot $R /bin/sh -c 'ip link add dev vcan0 type vcan && ip link set up vcan0' || fail "create vcan0"
read -r up _ < /proc/uptime; echo "vcan-vm: vcan0 up at ${up} s uptime"
if [ "$VM_INIT" = systemd ]; then
  # systemd as PID 1 in the host root: /var is the host's below, the VM's writes in RAM above (systemd's own state,
  # services' StateDirectory); the control dir and the script's unit go under /run, which the switch keeps
  mkdir -p /vmtmp/vupper /vmtmp/vwork
  mount -t overlay -o lowerdir=$R/var,upperdir=/vmtmp/vupper,workdir=/vmtmp/vwork overlay $R/var || fail "mount /var"
  mkdir -p $R/run/vcan-vm/ctl $R/run/systemd/system
  mount -o bind /ctl $R/run/vcan-vm/ctl || fail "bind the control dir"
  cp /ctl/vcan-vm.service $R/run/systemd/system/ || fail "copy the script's unit"
  # runtime masks: boot-time tmpfiles would walk (and whiteout) the host's /tmp over 9p for minutes
  for u in systemd-tmpfiles-setup.service systemd-tmpfiles-clean.timer; do
    ln -s /dev/null $R/run/systemd/system/$u
  done
  exec switch_root $R /lib/systemd/systemd --unit=vcan-vm.service --show-status=error
  fail "switch_root to systemd"
fi
echo "@BEGIN@"
env -i chroot $R /bin/sh /run/vcan-vm/run.sh </dev/null &
pid=$!
( sleep "$VM_TIMEOUT"; echo "@TIMEOUT@ after $VM_TIMEOUT s"; kill -9 $pid ) 2>/dev/null &
wd=$!
wait $pid
rc=$?
kill $wd 2>/dev/null
echo "$rc" > /ctl/exit_code
sync
echo "@EXIT@$rc"
poweroff -f
sleep 5
"""


def _init_script() -> str:
    return (
        _INIT.replace("@INIT_FAIL@", SENTINEL_INIT_FAIL)
        .replace("@EXIT@", SENTINEL_EXIT)
        .replace("@BEGIN@", SENTINEL_BEGIN)
        .replace("@TIMEOUT@", SENTINEL_TIMEOUT)
    )


def _read_module(path: Path) -> bytes:
    data = path.read_bytes()
    name = path.name
    if name.endswith(".xz"):
        return lzma.decompress(data)
    if name.endswith(".gz"):
        return gzip.decompress(data)
    if name.endswith(".zst"):
        zstd = shutil.which("zstd")
        if not zstd:
            raise VMUnavailable(f"{path} is zstd-compressed and `zstd` is missing (Debian package zstd)")
        return subprocess.run([zstd, "-dc", str(path)], check=True, stdout=subprocess.PIPE, timeout=60).stdout
    return data


class _Cpio:
    """Minimal writer for the cpio "newc" format the kernel unpacks as initramfs."""

    def __init__(self) -> None:
        self.buf = io.BytesIO()
        self.ino = 1

    def _entry(self, name: str, mode: int, data: bytes = b"", rdev: tuple[int, int] = (0, 0)) -> None:
        nameb = name.encode() + b"\0"
        fields = (self.ino, mode, 0, 0, 1, 0, len(data), 0, 0, rdev[0], rdev[1], len(nameb), 0)
        self.ino += 1
        hdr = b"070701" + b"".join(b"%08X" % f for f in fields)
        self.buf.write(hdr + nameb)
        self.buf.write(b"\0" * (-(len(hdr) + len(nameb)) % 4))
        self.buf.write(data)
        self.buf.write(b"\0" * (-len(data) % 4))

    def dir(self, name: str) -> None:
        self._entry(name, 0o040755)

    def file(self, name: str, data: bytes, perm: int = 0o644) -> None:
        self._entry(name, 0o100000 | perm, data)

    def symlink(self, name: str, target: str) -> None:
        self._entry(name, 0o120777, target.encode())

    def chardev(self, name: str, major: int, minor: int, perm: int = 0o600) -> None:
        self._entry(name, 0o020000 | perm, rdev=(major, minor))

    def finish(self) -> bytes:
        self.ino = 0
        self._entry("TRAILER!!!", 0)
        return self.buf.getvalue()


def _ensure_initramfs(kver: str, busybox: Path, modules: list[tuple[str, Path]], log: TextIO | None) -> Path:
    bb = busybox.read_bytes()
    init = _init_script().encode()
    key = hashlib.sha256()
    key.update(str(_INITRAMFS_FORMAT).encode())
    key.update(init)
    key.update(hashlib.sha256(bb).digest())
    for name, path in modules:
        st = path.stat()
        key.update(f"{name}:{path}:{st.st_size}:{st.st_mtime_ns}".encode())
    cache = _cache_root() / kver
    target = cache / f"initramfs-{key.hexdigest()[:16]}.cpio.gz"
    if target.is_file():
        return target
    t0 = time.monotonic()
    applets = subprocess.run(
        [str(busybox), "--list"], check=True, stdout=subprocess.PIPE, text=True, timeout=30
    ).stdout.split()
    cpio = _Cpio()
    for d in ("bin", "dev", "proc", "sys", "lib", "lib/modules", "newroot", "ctl", "tmp", "vmtmp"):
        cpio.dir(d)
    cpio.chardev("dev/console", 5, 1)
    cpio.chardev("dev/null", 1, 3, 0o666)
    cpio.file("bin/busybox", bb, 0o755)
    for applet in applets:
        if applet != "busybox" and "/" not in applet:
            cpio.symlink(f"bin/{applet}", "busybox")
    for name, path in modules:
        cpio.file(f"lib/modules/{name}.ko", _read_module(path))
    cpio.file("modules.order", "".join(f"{name}\n" for name, _ in modules).encode())
    cpio.file("init", init, 0o755)
    data = gzip.compress(cpio.finish(), compresslevel=6, mtime=0)
    cache.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=cache, prefix=".initramfs-")
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
    os.replace(tmp, target)  # atomic: concurrent builders produce identical files
    for old in cache.glob("initramfs-*.cpio.gz"):  # stale builds; a day's grace for parallel checkouts
        try:
            if old != target and time.time() - old.stat().st_mtime > 86400:
                old.unlink()
        except OSError:
            pass
    if log:
        print(
            f"vcan_vm: built {target} ({len(data) / 1e6:.1f} MB) in {time.monotonic() - t0:.1f} s", file=log, flush=True
        )
    return target


# --------------------------------------------------------------------------- running

_CHROOT_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


def _root_9p_opts() -> str:
    return os.environ.get("VCAN_VM_ROOT_9P_OPTS", "trans=virtio,version=9p2000.L,ro,msize=262144,cache=loose")


#: where the stubs of ``hide_modules`` are inside the VM (first on PYTHONPATH)
VM_PYHIDE = "/run/vcan-vm/pyhide"


def _run_sh(share: Path, env: dict[str, str] | None, hide: bool = False) -> str:
    python = _host_python()
    pythonpath = ([VM_PYHIDE] if hide else []) + [str(REPO_ROOT)]
    if os.environ.get("PYTHONPATH"):
        pythonpath.append(os.environ["PYTHONPATH"])
    base = {
        "PATH": f"{python.parent}:{_CHROOT_PATH}",
        "HOME": "/tmp",
        "TMPDIR": "/tmp",
        "LANG": "C.UTF-8",
        "TERM": "dumb",
        "VM_SHARE": str(share),
        "VM_PYTHON": str(python),
        "VM_REPO": str(REPO_ROOT),
        "PYTHONPATH": os.pathsep.join(pythonpath),
        "PYTHONDONTWRITEBYTECODE": "1",
        "PYTHONUNBUFFERED": "1",
    }
    base.update(env or {})
    lines = ["# generated by tools/vcan_vm/harness.py"]
    lines += [f"export {k}={shlex.quote(v)}" for k, v in base.items() if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", k)]
    lines += ['cd "$VM_SHARE" || exit 254', "exec /bin/sh /run/vcan-vm/script.sh 2>&1", ""]
    return "\n".join(lines)


#: the unit systemd (``init="systemd"``) starts instead of a target: the script as a oneshot service after
#: basic.target (journald, udevd and the rest of the host's early boot), its output on the console, then power-off
_SYSTEMD_UNIT = """[Unit]
Description=gearbox-vsensor vcan VM script
[Service]
Type=oneshot
TimeoutStartSec=infinity
StandardInput=null
StandardOutput=tty
StandardError=tty
TTYPath=/dev/console
ExecStart=/bin/sh -c 'echo "{sentinel_begin}"; timeout -s KILL {timeout} /bin/sh /run/vcan-vm/run.sh; rc=$$?; \\
[ $$rc = 137 ] && echo "{sentinel_timeout} after {timeout} s"; echo $$rc > /run/vcan-vm/ctl/exit_code; sync; \\
echo "{sentinel_exit}$$rc"; systemctl poweroff --force --force'
"""


def _qemu_cmd(assets: Assets, ctl: Path, share: Path, memory_mb: int, smp: int) -> list[str]:
    def virtfs(path: Path, tag: str, readonly: bool) -> list[str]:
        opts = f"local,path={path},mount_tag={tag},security_model=none,multidevs=remap"
        return ["-virtfs", opts + (",readonly=on" if readonly else "")]

    return [
        str(assets.qemu),
        "-accel",
        "tcg",  # KVM is present on these machines but hangs: never use it
        "-cpu",
        "max",  # host Python and numpy wheels need more than the qemu64 baseline
        "-m",
        str(memory_mb),
        "-smp",
        str(smp),
        "-nodefaults",
        "-no-user-config",
        "-nographic",
        "-no-reboot",
        "-serial",
        "stdio",
        "-monitor",
        "none",
        "-kernel",
        str(assets.kernel),
        "-initrd",
        str(assets.initramfs),
        # the kernel's boot log, info included, goes to the console (loglevel 7, after quiet: it wins; a hang shows
        # where), and the init lowers the console level to 3 (critical and worse, as before the watchdog)
        "-append",
        "console=ttyS0 quiet loglevel=7 panic=-1 mitigations=off random.trust_cpu=on",
        *virtfs(Path("/"), "hostroot", True),
        *virtfs(ctl, "ctl", False),
        *virtfs(share, "share", False),
    ]


def run_in_vm(
    script: str,
    timeout_s: float = 300,
    share_dir: Path | None = None,
    *,
    env: dict[str, str] | None = None,
    assets: Assets | None = None,
    memory_mb: int = 1024,
    smp: int = 2,
    stream: TextIO | None = None,
    init: str = "sh",
    boot_timeout_s: float = 120,
    boot_attempts: int = 3,
    hide_modules: tuple[str, ...] = (),
) -> VMResult:
    """Boot the VM, run ``script`` with ``/bin/sh`` inside the chroot of the host root, power off.

    ``init="systemd"`` boots the host's systemd as PID 1 in the host root instead, and runs the script as a
    oneshot service after basic.target (as root; the script may start units of its own from /run/systemd/system,
    see docs/vcan-vm.md). /var is then writable too (in RAM).

    ``script`` runs with vcan0 up, cwd = ``$VM_SHARE`` (= ``share_dir``, same absolute path inside
    and outside; a fresh temp dir when None, which the caller then owns), ``$VM_PYTHON`` = host
    interpreter, ``$VM_REPO`` = repo root (on PYTHONPATH), plus ``env``.  Its stdout and stderr go
    to the console: see :attr:`VMResult.script_output`.  ``stream`` receives the console live.

    A boot whose kernel has not started the init within ``boot_timeout_s`` (a normal one: ~3 s of VM time, under 6 s
    of wall time; 9-13 s on a loaded host) is killed and retried, up to ``boot_attempts`` boots in all; the last
    retry boots one CPU (``-smp 1``: the hangs reported for TCG happen while the kernel brings up the second CPU).
    Each retry is reported on stderr; :attr:`VMResult.boot_attempts` counts the boots. ``boot_timeout_s=None`` (or 0)
    turns the watchdog off.

    ``hide_modules``: top-level packages the VM's Python cannot import (:func:`_write_module_stubs`).

    Returns the script's exit status; raises :class:`VMTimeout` (QEMU killed) when the whole run
    takes longer than ``timeout_s`` (per boot), :class:`VMBootHang` when every boot hung before the init,
    :class:`VMError` when the VM died without reporting a status, :class:`VMUnavailable` when prerequisites are
    missing.
    """
    if assets is None:
        assets = ensure_vm_assets()
    if share_dir is None:
        share = Path(tempfile.mkdtemp(prefix="vcan-vm-share-"))
    else:
        share = Path(os.path.realpath(share_dir))
        share.mkdir(parents=True, exist_ok=True)
    if share == Path("/"):
        raise ValueError("share_dir must not be /")
    inner_timeout = max(5, int(timeout_s - _BOOT_MARGIN_S))
    _compile_repo()
    with tempfile.TemporaryDirectory(prefix="vcan-vm-ctl-") as ctl_name:
        ctl = Path(ctl_name)
        _write_control(ctl, script, share, {**_host_kernel_env(), **(env or {})}, hide_modules, init, inner_timeout)
        output, boot_s, total_s, attempt, cpus = _boot_with_retries(
            lambda cpus: _qemu_cmd(assets, ctl, share, memory_mb, cpus),
            smp,
            timeout_s,
            boot_timeout_s,
            boot_attempts,
            stream,
        )
        exit_file = ctl / "exit_code"
        exit_text = exit_file.read_text().strip() if exit_file.is_file() else ""
    rc = _script_status(output, exit_text, inner_timeout, timeout_s)
    return VMResult(
        returncode=rc, output=output, share_dir=share, boot_s=boot_s, total_s=total_s, boot_attempts=attempt, smp=cpus
    )


#: the repo's packages the VM's Python imports (``python -m tools.cli``)
_REPO_PACKAGES = ("firmware_model", "can_dbc", "tools")


def _compile_repo() -> None:
    """The repo's bytecode next to its sources (``__pycache__``, as an import writes it), before the boot: the VM's
    Python writes none (PYTHONDONTWRITEBYTECODE), so on a host that writes none either, each Python start in the VM
    compiled every repo module it imported under TCG. A checkout that cannot be written is left as it is."""
    import compileall

    prefix, sys.pycache_prefix = sys.pycache_prefix, None  # the VM's Python reads __pycache__ beside the sources
    try:
        for name in _REPO_PACKAGES:
            compileall.compile_dir(REPO_ROOT / name, quiet=2, workers=1)
    finally:
        sys.pycache_prefix = prefix


def _host_kernel_env() -> dict[str, str]:
    """``GVS_KERNEL_LIB`` = the host's compiled kernel (built now if needed), which the VM sees at the same path: the
    VM's HOME is /tmp, so without it a checkout whose installed library is stale would compile the kernel under TCG
    at every service start. Empty when the host has no compiled kernel (the VM then finds its own way)."""
    from firmware_model.onboard import ckernel

    try:
        lib, _ = ckernel.load("double")
    except ckernel.CoreUnavailable:
        return {}
    return {"GVS_KERNEL_LIB": str(Path(lib._name).resolve())}


def _write_control(
    ctl: Path, script: str, share: Path, env: dict | None, hide_modules: tuple, init: str, inner_timeout: int
) -> None:
    """The control directory the VM's init reads: the script, its wrapper, the module stubs, the unit, the params."""
    (ctl / "script.sh").write_text(script)
    (ctl / "run.sh").write_text(_run_sh(share, env, bool(hide_modules)))
    _write_module_stubs(ctl / "pyhide", hide_modules)
    if init not in ("sh", "systemd"):
        raise ValueError(f"init must be 'sh' or 'systemd', not {init!r}")
    if init == "systemd" and not Path("/lib/systemd/systemd").is_file():
        raise VMUnavailable("init='systemd' needs systemd on the host (apt install systemd udev)")
    (ctl / "vcan-vm.service").write_text(
        _SYSTEMD_UNIT.format(
            timeout=inner_timeout,
            sentinel_begin=SENTINEL_BEGIN,
            sentinel_timeout=SENTINEL_TIMEOUT,
            sentinel_exit=SENTINEL_EXIT,
        )
    )
    (ctl / "params").write_text(
        f"VM_SHARE={shlex.quote(str(share))}\nVM_TIMEOUT={inner_timeout}\n"
        f"VM_ROOT_9P_OPTS={shlex.quote(_root_9p_opts())}\nVM_INIT={init}\n"
    )


def _script_status(output: str, exit_text: str, inner_timeout: int, timeout_s: float) -> int:
    """The script's exit status from the exit file or the console's sentinel; the VM's failures raised."""
    m = re.search(rf"^{re.escape(SENTINEL_EXIT)}(\d+)\s*$", output, re.M)
    if SENTINEL_TIMEOUT in output:
        raise VMTimeout(
            f"script did not finish within {inner_timeout} s inside the VM (run timeout "
            f"{timeout_s:g} s); console tail:\n{output[-3000:]}",
            output,
        )
    if SENTINEL_INIT_FAIL in output:
        line = output[output.find(SENTINEL_INIT_FAIL) :].splitlines()[0]
        raise VMError(f"VM init failed: {line}; console tail:\n{output[-3000:]}", output)
    if exit_text.isdigit():
        rc = int(exit_text)
    elif m:
        rc = int(m.group(1))
    else:
        raise VMError(f"VM exited without reporting the script's exit status; console tail:\n{output[-3000:]}", output)
    return rc


def _write_module_stubs(directory: Path, names: tuple[str, ...]) -> None:
    """A package per name whose import raises ImportError, for the VM's PYTHONPATH (``VM_PYHIDE``).

    ``("asammdf",)`` saves ~8 s of each service start-up under TCG on a quiet host (~40 s on a loaded one):
    python-can imports asammdf (with pandas and sympy) at ``import can`` when it is installed, and nothing but an MF4
    log needs it.
    """
    for name in names:
        stub = directory / name
        stub.mkdir(parents=True)
        (stub / "__init__.py").write_text(f"raise ImportError('{name} is hidden in the vcan VM (hide_modules)')\n")


def _boot_with_retries(
    make_cmd, smp: int, timeout_s: float, boot_timeout_s: float, attempts: int, stream: TextIO | None
) -> tuple[str, float | None, float, int, int]:
    """Run QEMU; retry a boot that hung before the init (the last retry with one CPU). Returns the console, the boot
    and run times, the boots made and the CPUs of the last."""
    attempts = max(1, int(attempts))
    for attempt in range(1, attempts + 1):
        cpus = 1 if attempt > 1 and attempt == attempts else smp
        try:
            output, boot_s, total_s = _run_qemu(make_cmd(cpus), timeout_s, stream, boot_timeout_s)
            return output, boot_s, total_s, attempt, cpus
        except VMBootHang as exc:
            if attempt == attempts:
                raise VMBootHang(
                    f"boot {attempt} of {attempts} ({cpus} CPU{'s' if cpus > 1 else ''}): {exc}", exc.output
                ) from None
            last = exc.output.strip().splitlines()[-1:] or ["(no console output)"]
            print(
                f"vcan VM: boot {attempt} of {attempts} hung before the init ({boot_timeout_s:g} s; last console "
                f"line: {last[0][:200]}); QEMU killed, booting again"
                + (" with one CPU" if attempt + 1 == attempts and smp != 1 else ""),
                file=sys.stderr,
                flush=True,
            )
    raise AssertionError("unreachable")


def _run_qemu(
    cmd: list[str], timeout_s: float, stream: TextIO | None, boot_timeout_s: float | None = None
) -> tuple[str, float | None, float]:
    t0 = time.monotonic()
    deadline = t0 + timeout_s
    boot_deadline = t0 + boot_timeout_s if boot_timeout_s else None
    init_marker = INIT_MARKER.encode()
    proc = subprocess.Popen(
        cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True
    )
    buf = bytearray()
    boot_s = None
    marker = SENTINEL_BEGIN.encode()
    sel = selectors.DefaultSelector()
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    sel.register(fd, selectors.EVENT_READ)
    try:
        while True:
            remaining = deadline - time.monotonic()
            if boot_deadline is not None and init_marker in buf:
                boot_deadline = None
            # at the boot deadline, output still waiting in the pipe is read (below) before the boot counts as hung
            if boot_deadline is not None and time.monotonic() >= boot_deadline and not sel.select(0):
                _kill(proc)
                text = _clean(buf)
                raise VMBootHang(
                    f"the VM's kernel did not start the init within {boot_timeout_s:g} s; QEMU killed; "
                    f"console tail:\n{text[-3000:]}",
                    text,
                )
            if remaining <= 0:
                _kill(proc)
                text = _clean(buf)
                raise VMTimeout(f"VM run exceeded {timeout_s:g} s; QEMU killed; console tail:\n{text[-3000:]}", text)
            wait = min(remaining, 1.0, boot_deadline - time.monotonic() if boot_deadline is not None else 1.0)
            if not sel.select(max(0.0, wait)):
                continue
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            if boot_s is None:
                if marker in buf[-len(marker) :] + chunk:
                    boot_s = time.monotonic() - t0
            buf += chunk
            if stream is not None:
                stream.write(chunk.decode("utf-8", "replace").replace("\r", ""))
                stream.flush()
        try:
            proc.wait(timeout=max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired as exc:
            _kill(proc)
            text = _clean(buf)
            raise VMTimeout(
                f"QEMU did not exit within {timeout_s:g} s; killed; console tail:\n{text[-3000:]}", text
            ) from exc
    finally:
        sel.close()
        proc.stdout.close()
        if proc.poll() is None:
            _kill(proc)
    return _clean(buf), boot_s, time.monotonic() - t0


def _kill(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass


_ANSI = re.compile(r"\x1b(?:\[[0-9;?]*[A-Za-z]|c)")


def _clean(buf: bytes | bytearray) -> str:
    """Console bytes as text: \r and the firmware's terminal escape sequences removed."""
    return _ANSI.sub("", bytes(buf).decode("utf-8", "replace").replace("\r", ""))


# --------------------------------------------------------------------------- CLI

_CHECK_SCRIPT = r"""
set -e
echo "--- ip -details link show vcan0"
ip -details link show vcan0
echo "--- python-can round trip"
cat > roundtrip.py <<'EOF'
import json, time, can
t0 = time.perf_counter()
tx = can.Bus(interface="socketcan", channel="vcan0")
rx = can.Bus(interface="socketcan", channel="vcan0")
n, worst = 200, 0.0
start = time.perf_counter()
for i in range(n):
    t = time.perf_counter()
    tx.send(can.Message(arbitration_id=0x18FEEE00 + (i & 0xFF), is_extended_id=True, data=i.to_bytes(2, "big")))
    msg = rx.recv(timeout=2.0)
    assert msg is not None and msg.arbitration_id == 0x18FEEE00 + (i & 0xFF), msg
    worst = max(worst, time.perf_counter() - t)
mean = (time.perf_counter() - start) / n
tx.shutdown(); rx.shutdown()
print(json.dumps({"frames": n, "mean_ms": mean * 1e3, "worst_ms": worst * 1e3}))
EOF
T0=$(cat /proc/uptime)
"$VM_PYTHON" -c 'import can, firmware_model' && echo "python start + import can, firmware_model OK"
"$VM_PYTHON" roundtrip.py
echo "uptime at script start / end: ${T0%% *} / $(cut -d' ' -f1 /proc/uptime) s"
"""


def _cmd_check(args: argparse.Namespace) -> int:
    missing = vm_prerequisites()
    print("prerequisites: " + ("all present" if not missing else "MISSING: " + "; ".join(missing)))
    if missing:
        print(f"-> {INSTALL_HINT}", file=sys.stderr)
        return 2
    t0 = time.monotonic()
    assets = ensure_vm_assets(log=sys.stdout)
    print(
        f"kernel {assets.kernel} ({assets.kernel_version}); initramfs {assets.initramfs}; "
        f"modules {', '.join(assets.modules)} (assets ready in {time.monotonic() - t0:.2f} s)"
    )
    try:
        res = run_in_vm(
            _CHECK_SCRIPT, timeout_s=args.timeout, assets=assets, stream=sys.stdout if args.verbose else None
        )
    except (VMError, VMUnavailable) as exc:
        print(f"vcan_vm check FAILED: {exc}", file=sys.stderr)
        return 1
    if not args.verbose:
        print(res.script_output.rstrip())
    shutil.rmtree(res.share_dir, ignore_errors=True)
    boot = f"{res.boot_s:.2f}" if res.boot_s is not None else "?"
    print(
        f"timings: boot to script start {boot} s ({res.boot_attempts} boot(s)), whole run {res.total_s:.2f} s; "
        f"script exit status {res.returncode}"
    )
    return 0 if res.returncode == 0 else 1


def _cmd_install(args: argparse.Namespace) -> int:
    try:
        assets = ensure_vm_assets(install=True, log=sys.stdout)
    except VMUnavailable as exc:
        print(f"vcan_vm install FAILED: {exc.reason}", file=sys.stderr)
        return 1
    print(f"ready: kernel {assets.kernel_version}, initramfs {assets.initramfs}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    script = args.command if args.command is not None else sys.stdin.read()
    share = Path(args.share) if args.share else None
    try:
        res = run_in_vm(
            script, timeout_s=args.timeout, share_dir=share, stream=sys.stdout if args.verbose else None, init=args.init
        )
    except VMUnavailable as exc:
        print(f"vcan_vm: {exc.reason}", file=sys.stderr)
        return 2
    except VMError as exc:
        print(f"vcan_vm: {exc}", file=sys.stderr)
        return 1
    if not args.verbose:
        sys.stdout.write(res.script_output)
    if share is None:
        shutil.rmtree(res.share_dir, ignore_errors=True)
    return res.returncode


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.vcan_vm", description="QEMU VM with a real Linux vcan0 for integration tests."
    )
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("check", help="list prerequisites, boot, show vcan0, python-can round trip, timings")
    p.add_argument("--timeout", type=float, default=120)
    p.add_argument("-v", "--verbose", action="store_true", help="stream the whole console")
    p.set_defaults(func=_cmd_check)
    p = sub.add_parser("install", help="apt-get install what is missing and build the cached initramfs")
    p.set_defaults(func=_cmd_install)
    p = sub.add_parser("run", help="run a shell command (or a script on stdin) inside the VM")
    p.add_argument("-c", dest="command", help="script text (default: read stdin)")
    p.add_argument("--share", help="host directory shared writable as $VM_SHARE (default: temp, removed)")
    p.add_argument("--timeout", type=float, default=300)
    p.add_argument(
        "--init",
        choices=("sh", "systemd"),
        default="sh",
        help="sh: the script in a chroot of the host root (default); systemd: the host's systemd as PID 1, "
        "the script as a oneshot service (systemctl and journalctl work; docs/vcan-vm.md)",
    )
    p.add_argument("-v", "--verbose", action="store_true", help="stream the whole console")
    p.set_defaults(func=_cmd_run)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
