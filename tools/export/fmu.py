"""`gearbox-vsensor export-fmu`: the onboard sensor as an FMI 2.0 or 3.0 co-simulation FMU for HIL and SIL rigs.

Built from the same C as the ECU export (tools.export.c_bundle): the kernel, the variant's generated tables (double)
and a small FMI wrapper (tools.export.fmu_source; FMI 2 or 3 over one shared instance). Inside the FMU:
``modelDescription.xml``, the binary for this
platform (compiled here with the C compiler on the PATH) and the sources (an importer can rebuild it for another
platform). Communication step: 0.1 s or a multiple of it. Variables are named as the run-table columns
(docs/interfaces.md section 3) of the gearbox's drive: inputs ``engine_speed_rpm`` ... ``retarder_torque_nm`` (a
vehicle), ``input_speed_rpm``, ``input_torque_nm``, ``oil_temp_c``, ``ambient_temp_c`` (a fixed-ratio drive: its one
gear, no coolant, standing still, as replay maps its run table); outputs ``T_<id>_c``,
``W_<id>``, ``ttl_<id>_s`` for every published component, ``degraded_mode``, ``valid_flags``, ``frozen_flags``,
``model_oil_temp_c``, ``oil_innovation_c``, ``rejects_<reason>``; parameters ``variant``, ``initial_temp_c`` and the
limits ``limit_warning_<id>_c`` / ``limit_critical_<id>_c``. FMI 2 types them Real / Integer / String, FMI 3
Float64 / Int32 / String (the reject counters Int64). The FMI headers come from FMPy (``pip install fmpy``,
the optional extra ``fmu``), which also validates and simulates the FMU in the tests.

The time to limit is refreshed every 1 s by the kernel's ``gvs_ttl_refresh`` (the marched held-input system,
docs/sensor.md) against the limits as tuned, and the early warning is on, as in ``gearbox-vsensor replay``.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape

from firmware_model.errors import InputError
from firmware_model.onboard.ckernel import compiler
from firmware_model.onboard.records import REJECT_REASONS
from firmware_model.onboard.warning_levels import LIMIT_RANGE_C
from tools.export.fmu_source import fmu_c
from tools.outputs import OutputError, naming, outputs
from tools.published import description, ids, label_of

MODEL_ID = "gearbox_vsensor"
#: value-reference blocks (the C wrapper gets the same numbers through @BLOCKS@)
VR = dict(
    VR_INPUT=0,
    VR_T=100,
    VR_TTL=200,
    VR_MODEL_OIL=300,
    VR_INNOVATION=301,
    VR_LEVEL=400,
    VR_MODE=500,
    VR_VALID=501,
    VR_FROZEN=502,
    VR_REJECT=510,
    VR_WARNING=600,
    VR_CRITICAL=700,
    VR_INITIAL_TEMP=800,
    VR_VARIANT=900,
    VR_TIME=1000,
)
#: the inputs' descriptions (SENSOR_INPUTS fields)
INPUT_TEXT = {
    "speed_rpm": "engine speed [rpm] (NaN: not available, the last good value is held)",
    "torque_nm": "engine torque [N.m] (NaN: not available, the last good value is held)",
    "gear": "engaged gear, an integer in -2..14 (0 neutral; another value: the last good gear is held)",
    "oil_temp_c": "measured transmission oil temperature [degC] (NaN: not measured, the sump is modelled)",
    "ambient_temp_c": "ambient air temperature [degC] (NaN: the configured default)",
    "coolant_temp_c": "engine coolant temperature [degC] (NaN: the configured default)",
    "vehicle_speed_kmh": "vehicle speed [km/h] (NaN: 50 km/h)",
    "retarder_torque_nm": "retarder torque [N.m] (NaN: 0, not braking)",
}
#: the bits of valid_flags and frozen_flags (bit i: input i)
_BITS = "bit 0 speed, 1 torque, 2 gear, 3 oil, 4 ambient, 5 coolant, 6 vehicle speed, 7 retarder"
#: start values of the inputs: not available (NaN), so an input left unconnected reads as missing (the drive
#: inputs: degraded mode 2, levels 3 after 10 s) and not as a neutral gear or a stopped engine
INPUT_START = (float("nan"),) * 8
#: a fixed-ratio drive's inputs (docs/interfaces.md section 3.2, tools.drive_table): sensor input field -> (variable,
#: description); the others are not inputs of its FMU and hold what replay gives a fixed-ratio run table (the one
#: gear, coolant not available, vehicle speed and retarder torque 0: tools.drive_table.map_fixed_ratio)
FIXED_RATIO_INPUTS = {
    "speed_rpm": ("input_speed_rpm", "input shaft speed [rpm] (NaN: not available, the last good value is held)"),
    "torque_nm": ("input_torque_nm", "input shaft torque [N.m] (NaN: not available, the last good value is held)"),
    "oil_temp_c": ("oil_temp_c", INPUT_TEXT["oil_temp_c"]),
    "ambient_temp_c": ("ambient_temp_c", INPUT_TEXT["ambient_temp_c"]),
}
_FIXED_RATIO_BITS = (
    "bit 0 input speed, 1 input torque, 2 gear (the one gear), 3 oil, 4 ambient, 5 coolant (none), 6 vehicle speed "
    "(0), 7 retarder (0)"
)


def fmu_inputs(gearbox=None) -> list[tuple]:
    """(variable name, description, start, exposed) of each sensor input (SENSOR_INPUTS order) in the FMU of
    ``gearbox`` (as :func:`_variables`): a vehicle's eight as the run-table columns; a fixed-ratio drive's input
    speed, input torque, oil and ambient, the other four fixed at what replay maps a fixed-ratio run table to."""
    from firmware_model.service.options import SENSOR_INPUTS
    from tools.drive_table import fixed_ratio_gear

    desc = description(gearbox)
    if desc is None or desc.drive.kind != "fixed_ratio":
        return [(col, INPUT_TEXT[f], INPUT_START[i], True) for i, (f, col) in enumerate(SENSOR_INPUTS)]
    fixed = {"gear": float(fixed_ratio_gear(desc)), "vehicle_speed_kmh": 0.0, "retarder_torque_nm": 0.0}
    out = []
    for i, (f, col) in enumerate(SENSOR_INPUTS):
        if f in FIXED_RATIO_INPUTS:
            out.append((*FIXED_RATIO_INPUTS[f], INPUT_START[i], True))
        else:
            out.append((col, INPUT_TEXT[f], fixed.get(f, float("nan")), False))
    return out


def _fmi_headers() -> Path:
    try:
        import fmpy
    except ImportError:
        raise InputError(
            "export-fmu needs FMPy for the FMI headers: pip install fmpy (or the extra gearbox-vsensor[fmu])"
        ) from None
    return Path(fmpy.__file__).resolve().parent / "c-code"


def _platform_dir(fmi_version: int = 2) -> str:
    """The binaries folder: FMI 2's ``linux64``, FMI 3's platform tuple ``x86_64-linux``."""
    system = platform.system()
    if fmi_version == 3:
        machine = {"amd64": "x86_64", "arm64": "aarch64"}.get(platform.machine().lower(), platform.machine().lower())
        return f"{machine}-" + {"Linux": "linux", "Darwin": "darwin", "Windows": "windows"}.get(system, "linux")
    bits = "64" if sys.maxsize > 2**32 else "32"
    return {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(system, "linux") + bits


def _output(name, vr, typ, text) -> tuple:
    """A discrete output variable's row (see :func:`_variables`)."""
    return (name, vr, typ, "output", "discrete", None, text)


def _parameter(name, vr, start, text) -> tuple:
    """A fixed Real parameter's row (see :func:`_variables`)."""
    return (name, vr, "Real", "parameter", "fixed", float(start), text)


def _variables(limits, gearbox=None) -> list[tuple]:
    """(name, vr, type, causality, variability, start or None, description) of every variable; the per-component
    ones for each component ``gearbox`` (the sensor, or its parameter set or description; None: the default
    gearbox) publishes, in its order."""
    desc, published = description(gearbox), ids(gearbox)
    if len(published) > VR["VR_TTL"] - VR["VR_T"]:
        raise InputError(
            f"the FMU numbers at most {VR['VR_TTL'] - VR['VR_T']} published components; this gearbox publishes "
            f"{len(published)}"
        )
    # every input is discrete: the sensor samples its inputs every 0.1 s and holds them, as a CAN signal is held
    # between frames; an importer holds them between samples instead of interpolating (an interpolated gear 8.3 is
    # rejected, and FMPy interpolating 0 x NaN + 1 x value read the first sample after a gap as NaN)
    v = [
        (name, VR["VR_INPUT"] + i, "Real", "input", "discrete", start, text)
        for i, (name, text, start, exposed) in enumerate(fmu_inputs(gearbox))
        if exposed
    ]
    bits = _FIXED_RATIO_BITS if desc is not None and desc.drive.kind == "fixed_ratio" else _BITS
    for i, c in enumerate(published):
        v.append(_output(f"T_{c}_c", VR["VR_T"] + i, "Real", f"{label_of(c, desc)} [degC]"))
    for i, c in enumerate(published):
        text = f"warning level of {c}: 0 normal, 1 warning, 2 critical, 3 not available"
        v.append(_output(f"W_{c}", VR["VR_LEVEL"] + i, "Integer", text))
    for i, c in enumerate(published):
        text = (
            f"time to the warning limit of {c} with the inputs held [s] (inf: not within 23 days, NaN: not available)"
        )
        v.append(_output(f"ttl_{c}_s", VR["VR_TTL"] + i, "Real", text))
    v += [
        _output("model_oil_temp_c", VR["VR_MODEL_OIL"], "Real", "the open-loop twin's sump"),
        _output("oil_innovation_c", VR["VR_INNOVATION"], "Real", "measured - model oil [K]"),
        _output(
            "degraded_mode",
            VR["VR_MODE"],
            "Integer",
            "0 normal, 1 oil modelled, 2 drive inputs missing (holding), 3 not initialised (no oil reading yet)",
        ),
        _output("valid_flags", VR["VR_VALID"], "Integer", "bit i set: input i valid this step (" + bits + ")"),
        _output("frozen_flags", VR["VR_FROZEN"], "Integer", "bit i set: input i frozen (" + bits + ")"),
    ]
    v += [
        _output(f"rejects_{r}", VR["VR_REJECT"] + i, "Integer", f"inputs rejected or repaired so far: {r}")
        for i, r in enumerate(REJECT_REASONS)
    ]
    for i, c in enumerate(published):
        v.append(
            _parameter(
                f"limit_warning_{c}_c", VR["VR_WARNING"] + i, limits.warning_c[i], f"warning limit of {c} [degC]"
            )
        )
        v.append(
            _parameter(
                f"limit_critical_{c}_c", VR["VR_CRITICAL"] + i, limits.critical_c[i], f"critical limit of {c} [degC]"
            )
        )
    text = "start temperature of every node [degC] (NaN: the first oil input, else ambient)"
    v.append(_parameter("initial_temp_c", VR["VR_INITIAL_TEMP"], float("nan"), text))
    return v


def _unit(name: str, typ: str) -> str | None:
    """The unit of a Real variable, from its name's suffix (the run-table convention); None: no unit."""
    if typ != "Real":
        return None
    if name == "oil_innovation_c":
        return "K"
    for suffix, unit in (("_c", "degC"), ("_rpm", "rpm"), ("_nm", "N.m"), ("_kmh", "km/h"), ("_s", "s")):
        if name.endswith(suffix):
            return unit
    return None


#: the units the variables use, as FMI BaseUnit attributes (SI exponents, factor and offset to SI)
UNITS = {
    "degC": 'K="1" offset="273.15"',
    "K": 'K="1"',
    "s": 's="1"',
    "rpm": 's="-1" rad="1" factor="0.10471975511965977"',
    "N.m": 'kg="1" m="2" s="-2"',
    "km/h": 'm="1" s="-1" factor="0.2777777777777778"',
}


def _unit_definitions() -> str:
    rows = "\n".join(f'    <Unit name="{escape(u)}"><BaseUnit {base}/></Unit>' for u, base in UNITS.items())
    return f"  <UnitDefinitions>\n{rows}\n  </UnitDefinitions>"


#: the C files an importer compiles (FMI 2 SourceFiles, FMI 3 sources/buildDescription.xml)
SOURCE_FILES = ("gvs_kernel.c", "gvs_tables.c", "gvs_sensor.c", "fmu.c")


def build_description() -> str:
    """sources/buildDescription.xml of an FMI 3 FMU: how an importer rebuilds the binary from the sources."""
    files = "\n".join(f'      <SourceFile name="{n}"/>' for n in SOURCE_FILES)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiBuildDescription fmiVersion="3.0">
  <BuildConfiguration modelIdentifier="{MODEL_ID}">
    <SourceFileSet language="C99">
{files}
    </SourceFileSet>
  </BuildConfiguration>
</fmiBuildDescription>
"""


def _xml_value(x: float) -> str:
    return "NaN" if x != x else repr(float(x))


def model_description(variant: str, limits, guid: str, fmi_version: int = 2, gearbox=None) -> str:
    """modelDescription.xml of the FMU (FMI ``fmi_version``); ``gearbox``: the sensor, or its parameter set or
    description, whose published components it outputs (None: the default gearbox)."""
    if fmi_version == 3:
        return _model_description_3(variant, limits, guid, gearbox)
    rows, outputs = [], []
    for k, (name, vr, typ, caus, var, start, desc) in enumerate(_variables(limits, gearbox), start=1):
        attrs = f'name="{escape(name)}" valueReference="{vr}" causality="{caus}" variability="{var}"'
        if caus == "parameter":
            attrs += ' initial="exact"'
        unit = _unit(name, typ)
        type_attrs = (f' unit="{escape(unit)}"' if unit else "") + (
            f' start="{_xml_value(start)}"' if start is not None else ""
        )
        inner = f"<{typ}{type_attrs}/>"
        rows.append(f'    <ScalarVariable {attrs} description="{escape(desc)}">{inner}</ScalarVariable>')
        if caus == "output":
            outputs.append(k)
    rows.append(
        f'    <ScalarVariable name="variant" valueReference="{VR["VR_VARIANT"]}" causality="parameter" '
        f'variability="fixed" initial="exact" description="gearbox variant of the tables">'
        f'<String start="{escape(variant)}"/></ScalarVariable>'
    )
    unknowns = "\n".join(f'      <Unknown index="{k}"/>' for k in outputs)
    sources = "\n".join(f'      <File name="{n}"/>' for n in SOURCE_FILES)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="gearbox-vsensor {escape(variant)}" guid="{guid}"
  description="Onboard virtual temperature sensor of a {escape(variant)} {_kind(gearbox)} (0.1 s step{_said(gearbox)})"
  generationTool="gearbox-vsensor export-fmu" variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{MODEL_ID}" canHandleVariableCommunicationStepSize="false"
    canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="false">
    <SourceFiles>
{sources}
    </SourceFiles>
  </CoSimulation>
{_unit_definitions()}
  <DefaultExperiment startTime="0" stepSize="0.1"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{unknowns}
    </Outputs>
    <InitialUnknowns>
{unknowns}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


#: FMI 3 type of each FMI 2 type (the reject counters are Int64 in FMI 3: they count a whole life)
_FMI3_TYPE = {"Real": "Float64", "Integer": "Int32", "String": "String"}


def _kind(gearbox) -> str:
    """What the gearbox is, for the FMU's description: a vehicle's range-splitter gearbox (the GRS905's words, as
    before), a fixed-ratio drive's fixed-ratio gearbox."""
    desc = description(gearbox)
    return "fixed-ratio gearbox" if desc is not None and desc.drive.kind == "fixed_ratio" else "range-splitter gearbox"


def _options_words(sensor) -> str:
    """The sensor options of this build that differ from the defaults, for the FMU's description (FMUs of one
    gearbox built with two configurations, a rig's held sump and a vehicle's, differed only in their GUID)."""
    import dataclasses

    from firmware_model.onboard.records import SensorOptions

    options = getattr(sensor, "options", None)
    if options is None:
        return ""
    default = SensorOptions()
    moved = [
        f"{f.name} = {getattr(options, f.name)!r}"
        for f in dataclasses.fields(SensorOptions)
        if getattr(options, f.name) != getattr(default, f.name)
    ]
    rig = " a rig's configuration (the sump conditioned from outside);" if getattr(sensor, "rig", False) else ""
    return f";{rig} options {', '.join(moved)}" if moved or rig else ""


def _said(sensor) -> str:
    """:func:`_options_words`, escaped for an XML attribute."""
    return escape(_options_words(sensor), {'"': "&quot;"})


def _model_description_3(variant: str, limits, guid: str, gearbox=None) -> str:
    rows, outputs = [], []
    for name, vr, typ, caus, var, start, desc in _variables(limits, gearbox):
        t3 = "Int64" if name.startswith("rejects_") else _FMI3_TYPE[typ]
        attrs = f'name="{escape(name)}" valueReference="{vr}" causality="{caus}" variability="{var}"'
        unit = _unit(name, typ)
        if unit:
            attrs += f' unit="{escape(unit)}"'
        if start is not None:
            attrs += f' start="{_xml_value(start)}"'
        rows.append(f'    <{t3} {attrs} description="{escape(desc)}"/>')
        if caus == "output":
            outputs.append(vr)
    rows.append(
        f'    <String name="variant" valueReference="{VR["VR_VARIANT"]}" causality="parameter" '
        f'variability="fixed" description="gearbox variant of the tables"><Start value="{escape(variant)}"/>'
        f"</String>"
    )
    rows.insert(
        0,
        f'    <Float64 name="time" valueReference="{VR["VR_TIME"]}" causality="independent" '
        f'variability="continuous" unit="s" description="simulation time [s]"/>',
    )
    structure = "\n".join(f'    <Output valueReference="{vr}"/>' for vr in outputs)
    structure += "\n" + "\n".join(f'    <InitialUnknown valueReference="{vr}"/>' for vr in outputs)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="gearbox-vsensor {escape(variant)}" instantiationToken="{guid}"
  description="Onboard virtual temperature sensor of a {escape(variant)} {_kind(gearbox)} (0.1 s step{_said(gearbox)})"
  generationTool="gearbox-vsensor export-fmu" variableNamingConvention="flat">
  <CoSimulation modelIdentifier="{MODEL_ID}" canHandleVariableCommunicationStepSize="false"
    fixedInternalStepSize="0.1" canGetAndSetFMUState="false" canSerializeFMUState="false"/>
{_unit_definitions()}
  <DefaultExperiment startTime="0" stepSize="0.1"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
{structure}
  </ModelStructure>
</fmiModelDescription>
"""


def _blocks(variant: str, guid: str, gearbox=None) -> str:
    lines = [f"#define {k} {v}u" for k, v in VR.items()]
    inputs = fmu_inputs(gearbox)
    start = ", ".join("NAN" if x != x else repr(x) for _, _, x, _ in inputs)
    exposed = ", ".join(str(int(e)) for *_, e in inputs)
    lo, hi = LIMIT_RANGE_C
    lines += [f"#define LIMIT_LO_C {lo!r}", f"#define LIMIT_HI_C {hi!r}", f'#define LIMIT_RANGE_TEXT "{lo:g}..{hi:g}"']
    from firmware_model.components import PUBLISHED

    pub = tuple(getattr(gearbox, "published", None) or PUBLISHED)  # the published ids, for the refusals' sentences
    names = ", ".join(f'"{c}"' for c in pub)
    lines += [f"static const char *const PUB_NAMES[] = {{{names}}};", f"#define N_PUB_NAMES {len(pub)}"]
    lines += [
        f"static const double INPUT_START[GVS_N_INPUTS] = {{{start}}};",
        "/* 1: an input of the FMU; 0: fixed at its start (a fixed-ratio drive's gear, vehicle speed ...) */",
        f"static const int INPUT_EXPOSED[GVS_N_INPUTS] = {{{exposed}}};",
        f'#define GVS_GUID "{guid}"',
        f'#define GVS_VARIANT "{variant}"',
    ]
    return "\n".join(lines)


def export_fmu(out_path, variant: str | None = None, config_path=None, fmi_version: int = 2) -> Path:
    """Build the FMU (FMI ``fmi_version``, 2 or 3) at ``out_path`` (a .fmu file, written atomically; a symbolic link
    is written through). Needs a C compiler and FMPy's headers."""
    headers = _fmi_headers()
    cc = compiler()
    if cc is None:
        raise InputError("export-fmu needs a C compiler (cc, gcc or clang) to build the FMU's binary")
    out = Path(out_path)
    if fmi_version not in (2, 3):
        raise InputError(f"--fmi {fmi_version}: the FMU is built for FMI 2 or 3")
    if out.suffix != ".fmu":
        raise InputError(f"{out}: the FMU file name must end in .fmu")
    # the FMU to a temporary file beside it (made now: an unwritable directory fails before the build), renamed
    # onto --out when complete; on any failure it is removed (tools.outputs)
    with outputs(("--out", out_path)) as (tmp_fmu,), tempfile.TemporaryDirectory() as tmp:
        try:
            fmu_dir = _build(Path(tmp), variant, config_path, fmi_version, cc, headers)
        except (OSError, OutputError) as exc:  # the build directory, not --out: say so
            cause = exc if isinstance(exc, OSError) else exc.cause
            where = f" ({cause.filename})" if getattr(cause, "filename", None) else ""
            raise InputError(
                f"--out {os.fspath(out_path)}: cannot build the FMU: {cause.strerror or cause}{where} "
                f"(the build runs in the temporary directory {tempfile.gettempdir()})"
            ) from None
        with naming(tmp_fmu), zipfile.ZipFile(tmp_fmu, "w", zipfile.ZIP_DEFLATED) as z:
            for p in sorted(fmu_dir.rglob("*")):
                if p.is_file():
                    z.write(p, p.relative_to(fmu_dir).as_posix())
    return out


def _build(tmp: Path, variant: str, config_path, fmi_version: int, cc: str, headers) -> Path:
    """The FMU's tree in ``tmp``/fmu: the sources, modelDescription.xml and the binary compiled for this platform."""
    from tools.export.c_bundle import sensor_files

    variant_name, sensor = _variant_and_sensor(variant, config_path)
    src = tmp / "fmu" / "sources"
    src.mkdir(parents=True)
    # the sensor's sources of export-c's double build (not its test vectors: no plant run for an FMU)
    for name, content in sensor_files(sensor, "double").items():
        if isinstance(content, bytes):
            (src / name).write_bytes(content)
        else:
            (src / name).write_text(content)
    guid = "{" + hashlib.sha256((src / "gvs_tables.c").read_bytes()).hexdigest()[:32] + "}"
    (src / "fmu.c").write_text(fmu_c(fmi_version, _blocks(variant_name, guid, sensor)))
    (tmp / "fmu" / "modelDescription.xml").write_text(
        model_description(variant_name, sensor.limits, guid, fmi_version, sensor)
    )
    binaries = tmp / "fmu" / "binaries" / _platform_dir(fmi_version)
    binaries.mkdir(parents=True)
    suffix = {"Windows": ".dll", "Darwin": ".dylib"}.get(platform.system(), ".so")
    if fmi_version == 3:
        (src / "buildDescription.xml").write_text(build_description())
    cmd = [
        cc,
        "-std=c99",
        "-O2",
        "-fPIC",
        "-shared",
        "-fno-fast-math",
        f"-I{headers}",
        f"-I{src}",
        *(str(src / n) for n in SOURCE_FILES),
        "-o",
        str(binaries / (MODEL_ID + suffix)),
        "-lm",
    ]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise InputError(f"the FMU's binary did not compile: {res.stderr.strip()[:400]}")
    return tmp / "fmu"


def _variant_and_sensor(variant: str, config_path):
    """The variant name and the sensor the export describes: its published components and warning limits (as
    tools.export.c_bundle.export_c)."""
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.export.c_bundle import export_config

    cfg, params = export_config(variant, config_path)
    return params.variant, VirtualSensor(params, config=cfg, core="numpy")
