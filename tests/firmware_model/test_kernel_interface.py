"""The kernel's interface is described once (firmware_model/onboard/kernel_interface.py): the checked-in header is what
it generates, the ctypes classes agree with a compiled probe of the header, the table builder fills exactly the
struct's fields, and the kernel source retypes none of the shared constants.
"""

from __future__ import annotations

import ctypes as C
import re
import subprocess
from pathlib import Path

import pytest

from firmware_model.onboard import ckernel
from firmware_model.onboard import kernel_interface as KI

C_DIR = Path(KI.HEADER_PATH).parent
CC = ckernel.compiler()


def test_the_header_is_what_the_interface_generates():
    diff = KI.first_difference(KI.HEADER_PATH.read_text(), KI.header_text())
    assert diff is None, diff


def test_a_hand_edit_of_the_header_is_named_with_its_line_and_the_command_that_regenerates():
    text = KI.header_text()
    lines = text.splitlines()
    i = next(k for k, line in enumerate(lines) if "GVS_MAX_NODES 96" in line)
    edited = "\n".join(lines[:i] + [lines[i].replace("96", "97")] + lines[i + 1 :]) + "\n"
    msg = KI.first_difference(edited, text)
    assert msg is not None and f"line {i + 1} " in msg and KI.REGENERATE in msg
    assert KI.first_difference(text + "/* extra */\n", text) is not None


def test_check_mode_exits_1_on_a_stale_header(tmp_path, monkeypatch, capsys):
    stale = tmp_path / "gvs_kernel.h"
    stale.write_text(KI.header_text().replace("int32_t due, measured, row;", "int32_t due, row, measured;"))
    monkeypatch.setattr(KI, "HEADER_PATH", stale)
    assert KI.main(["--check"]) == 1
    assert "differs" in capsys.readouterr().out
    assert KI.main(["--write"]) == 0 and KI.main(["--check"]) == 0


def _probe_source() -> str:
    lines = ["#include <stdio.h>", "#include <stddef.h>", '#include "gvs_kernel.h"', "int main(void) {"]
    for s in KI.STRUCTS:
        lines.append(f'printf("{s.py_name} - %zu\\n", sizeof({s.c_name}));')
        lines += [f'printf("{s.py_name} {f.name} %zu\\n", offsetof({s.c_name}, {f.name}));' for f in s.fields]
    for c in KI.CAPACITIES + KI.DEFINES:
        fmt = "%d" if isinstance(c.value, int) else "%.17g"
        cast = "(int)" if isinstance(c.value, int) else "(double)"
        lines.append(f'printf("#{c.name} {fmt}\\n", {cast}GVS_{c.name});')
    for e in KI.ENUMS:
        lines += [f'printf("#{n} %d\\n", (int){("GVS_" + n)});' for n, _ in e.items]
    return "\n".join(lines + ["return 0; }"]) + "\n"


@pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on the PATH to compile the header's probe")
@pytest.mark.parametrize("real", ["double", "float"])
def test_ctypes_layouts_and_constants_equal_the_compiled_header(real, tmp_path):
    """sizeof and offsetof of every field of every struct, and every #define and enum value, as a C compiler sees
    the header, against the ctypes classes and the Python constants."""
    (tmp_path / "probe.c").write_text(_probe_source())
    flags = ["-DGVS_REAL_FLOAT"] if real == "float" else []
    exe = tmp_path / "probe"
    res = subprocess.run(
        [CC, "-std=c99", "-Wall", "-Werror", *flags, "-I", str(C_DIR), str(tmp_path / "probe.c"), "-o", str(exe)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split("\n")
    S = ckernel.structs(C.c_float if real == "float" else C.c_double)
    want = {}
    for s in KI.STRUCTS:
        want[f"{s.py_name} -"] = C.sizeof(S[s.py_name])
        want.update({f"{s.py_name} {f.name}": getattr(S[s.py_name], f.name).offset for f in s.fields})
    consts = {f"#{c.name}": c.value for c in KI.CAPACITIES + KI.DEFINES}
    consts.update({f"#{n}": v for e in KI.ENUMS for n, v in e.items})
    got = {line.rsplit(" ", 1)[0]: line.rsplit(" ", 1)[1] for line in out if line}
    bad = [f"{k}: C {got.get(k)}, Python {v}" for k, v in want.items() if got.get(k) != str(v)]
    bad += [
        f"{k}: C {got.get(k)}, Python {v!r}" for k, v in consts.items() if got.get(k) is None or (float(got[k]) != v)
    ]
    assert not bad, "the header and the Python side disagree:\n" + "\n".join(bad[:20])
    assert len(got) == len(want) + len(consts)


def test_the_table_builder_fills_exactly_the_structs_fields():
    from firmware_model.onboard.kernel_tables import table_arrays, vehicle_arrays
    from firmware_model.onboard.params import SensorParams
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters

    sp: SensorParams = VirtualSensor(load_parameters("GRS905"), core="numpy").sp
    arrays = table_arrays(sp)
    assert list(arrays) == [f.name for f in KI.STRUCT["Tables"].fields]
    for f in KI.STRUCT["Tables"].fields:
        v = arrays[f.name]
        if f.ctype in (KI.PREAL, KI.PIDX):
            assert v.ndim == 1 and v.dtype.kind == ("f" if f.ctype == KI.PREAL else "i"), f.name
        else:
            assert isinstance(v, int if f.ctype == KI.I32 else float) or hasattr(v, "dtype"), f.name
    assert arrays["n_pub"] == len(sp.reduced.published) <= KI.MAX_PUB
    assert arrays["n_gears"] == sp.reduced.speed_coef.shape[0] <= KI.MAX_GEARS
    for name in ("published_index", "warning_c", "ttl_relin"):
        assert arrays[name].size == arrays["n_pub"], name
    assert list(vehicle_arrays(sp, 2)) == [f.name for f in KI.STRUCT["Vehicle"].fields]
    with pytest.raises(KeyError, match="fills no n_recirc.*fills wrong_key"):
        KI.struct_values(KI.STRUCT["Tables"], {**{k: v for k, v in arrays.items() if k != "n_recirc"}, "wrong_key": 0})


#: numbers the kernel must read from the header, never retype: the march's, the effect codes, the speed columns
RETYPED = [
    r"#define\s+(MARCH|TTL|HERMITE|COUPLING)_",
    r"\benum\s*\{\s*(P_|LEVEL_|MODE_|MAIN|RJ_)",
    r"_effect\[t\]\s*==\s*\d",
    r"n_speed\s*\+\s*\d\]",
    r"cooler_code\s*==\s*\d",
    r"\bcase\s+\d+\s*:",
    r"\[28\]",
]


def test_the_kernel_source_retypes_no_shared_constant():
    src = (C_DIR / "gvs_kernel.c").read_text()
    found = [(p, m.group(0)) for p in RETYPED for m in re.finditer(p, src)]
    assert not found, f"gvs_kernel.c retypes constants of kernel_interface.py (use the header's GVS_*): {found[:8]}"


def test_the_python_side_reads_the_shared_constants_from_the_interface():
    from firmware_model.onboard import held_march, reduce, time_to_limit
    from firmware_model.physics.kinematics import SPEED_NAMES

    assert held_march.MARCH_D_FRAC is KI.MARCH_D_FRAC and held_march.TTL_QUANTUM_S is KI.TTL_QUANTUM_S
    assert time_to_limit.COUPLING_MARGIN is KI.COUPLING_MARGIN and reduce.P_RHO == KI.P_RHO
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters

    rp = VirtualSensor(load_parameters("GRS905"), core="numpy").reduced
    assert SPEED_NAMES[rp.pump_speed_col] == SPEED_NAMES[rp.churn_speed_col] == "LS"
    assert SPEED_NAMES[rp.output_speed_col] == "OS"
    assert not hasattr(KI, "SPEED_COL_LAYSHAFT") and "SPEED_COL" not in KI.header_text()
    onboard = Path(reduce.__file__).parent
    bare = [
        f"{p.name}:{i + 1}"
        for p in onboard.glob("*.py")
        for i, line in enumerate(p.read_text().splitlines())
        if re.search(r"speed_coef\[[^\]]*,\s*\d\]|_effect\s*==\s*\d|_effect\[t\]\s*==\s*\d", line)
    ]
    assert not bare, f"bare speed columns or effect codes (use kernel_interface's names): {bare}"
