"""A DBC per gearbox (can_dbc.generate, `gearbox-vsensor export-dbc`): the GRS905's generated DBC is the shipped
one byte for byte; another description's loads strictly, lays out every published component by the packing rule
of docs/can.md, and its frames encode and decode one value per component with the encoders, the readback and the
decoder given that DBC; too many components is one sentence, exit 2."""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import cantools
import pytest

from can_dbc import dbc, generate
from can_dbc.decoder import J1939Decoder
from can_dbc.encoder import OutputEncoder, RigEncoder
from can_dbc.j1939 import pgn_of
from can_dbc.readback import decode_outputs, decode_rig
from firmware_model.description import load_description, shipped_descriptions
from tools.cli import main
from tools.cli.export_dbc import component_meanings

REPO = Path(__file__).resolve().parents[2]
SHIPPED = REPO / "can_dbc" / dbc.DBC_NAME


@pytest.fixture(scope="module")
def r1(tmp_path_factory) -> Path:
    """docs/description.md's single-stage reducer R1: 7 published components (P, W, B1..B4, oil)."""
    text = (REPO / "docs" / "description.md").read_text(encoding="utf-8")
    f = tmp_path_factory.mktemp("r1") / "r1.toml"
    f.write_text(re.search(r"```toml\n(.*?)```", text, re.S).group(1), encoding="utf-8")
    return f


def test_the_grs905_dbc_is_generated_byte_for_byte(tmp_path, capsys):
    d = load_description("GRS905")
    text = generate.generate_dbc([p.id for p in d.published], component_meanings(d))
    assert text == SHIPPED.read_text(encoding="utf-8")
    out = tmp_path / "g.dbc"
    assert main(["export-dbc", "--out", str(out)]) == 0
    assert out.read_bytes() == SHIPPED.read_bytes()
    assert "28 published components" in capsys.readouterr().out


def test_the_dbc_says_what_the_retarder_torque_refers_to_as_the_decoder_takes_it():
    """The ERC1 comment said "Nm = percent / 100 x the configured retarder reference torque", where the decoder (and
    docs/can.md) takes RC's SPN 556 from the retarder once received, the configured one only until then; the TP
    comment named EC1 only, where RC is reassembled too, and cited can_dbc/adapter.py for the reassembly."""
    db = cantools.database.load_file(str(SHIPPED), strict=True)
    erc1 = db.get_message_by_name("ERC1").comment
    assert "RC (PGN 65249, SPN 556, by TP.BAM from the retarder's source address) once received" in erc1, erc1
    assert "else the configured one ([can] retarder_reference_torque_nm)" in erc1, erc1
    tp = db.get_message_by_name("TP_CM").comment
    assert "RC (PGN 65249" in tp and "SPN 556" in tp, tp
    # the file the TP comment cites for the reassembly is the one that does it (it cited can_dbc/adapter.py, the
    # public API's re-exports, where the TP.CM/TP.DT handling is the decoder's)
    (cited,) = re.findall(r"\(((?:can_dbc/)\w+\.py)\)", tp)
    assert (REPO / cited).is_file(), cited
    assert Path(J1939Decoder._tp_dt.__code__.co_filename) == REPO / cited, cited
    ref = J1939Decoder(retarder_ref_torque_nm=1000.0)  # the precedence the comment states
    ref.rc_ref_torque_nm = 3500.0
    assert ref.retarder_ref_in_use_nm == 3500.0


def test_the_layout_rule_reproduces_todays_pgns_and_extends():
    ids = [f"C{i}" for i in range(28)]
    lay = generate.frame_layout(ids)
    assert [f.pgn for f in lay.temp] == list(range(0xFF40, 0xFF47))
    assert [f.name for f in lay.warn] == ["GBX_WARN"] and lay.warn[0].pgn == 0xFF47
    assert [f.pgn for f in lay.ttl] == list(range(0xFF48, 0xFF4F)) and lay.status_pgn == 0xFF4F
    assert [f.pgn for f in lay.rig] == list(range(0xFF50, 0xFF57))
    for n in (1, 7, 29, 33, 100, generate.MAX_COMPONENTS):
        lay = generate.frame_layout([f"C{i}" for i in range(n)])
        frames = (*lay.temp, *lay.warn, *lay.ttl, *lay.rig)
        pgns = sorted([f.pgn for f in frames] + [lay.status_pgn])
        assert pgns == list(range(0xFF40, 0xFF40 + generate.frames_needed(n)))  # contiguous, no PGN twice
        assert pgns[-1] <= 0xFFFF
        for kind in (lay.temp, lay.warn, lay.ttl, lay.rig):
            assert [c for f in kind for c in f.components] == [f"C{i}" for i in range(n)]
        assert len(lay.warn) == math.ceil(n / 32) and len(lay.temp) == math.ceil(n / 4)
    with pytest.raises(generate.GenerateError, match=r"at most 244 fit"):
        generate.frame_layout([f"C{i}" for i in range(generate.MAX_COMPONENTS + 1)])


def test_bad_ids_are_one_sentence():
    with pytest.raises(generate.GenerateError, match="both make the signal name T_A_b"):
        generate.generate_dbc(["A.b", "A_b"])
    with pytest.raises(generate.GenerateError, match="quote or white space"):
        generate.generate_dbc(['A"'])
    with pytest.raises(generate.GenerateError, match="over 32 characters"):
        generate.generate_dbc(["X" * 29])
    with pytest.raises(generate.GenerateError, match="at least one"):
        generate.generate_dbc([])


def _roundtrip(db: dbc.CanDatabase, ids: list[str]) -> None:
    """One distinct value per component through the encoders, the cantools readback and the decoder."""
    temps = {c: 20.0 + 1.5 * i for i, c in enumerate(ids)}
    levels = {c: i % 3 for i, c in enumerate(ids)}
    ttl = {c: [math.inf, None, 60.0 + i][i % 3] for i, c in enumerate(ids)}
    enc = OutputEncoder(database=db)
    assert enc.components == tuple(ids)
    frames = enc.encode(temps, levels, ttl, {"model_oil_temp_c": 70.0})
    assert len(frames) == 2 * math.ceil(len(ids) / 4) + math.ceil(len(ids) / 32) + 1
    out = decode_outputs(frames, database=db)
    assert out["temps_c"] == temps and out["levels"] == levels and out["ttl_s"] == ttl
    assert out["status"]["max_warning_level"] == (2 if len(ids) > 2 else max(levels.values()))
    last = ids[-1]
    dm1 = decode_outputs([OutputEncoder(database=db).encode_dm1({last: 2})], database=db)["dm1"]
    assert dm1["dtc"]["component"] == last and dm1["dtc"]["spn"] == generate.SPN_FIRST + len(ids) - 1
    rig = RigEncoder(database=db).encode(temps)
    assert decode_rig(rig, database=db) == temps
    decoder = J1939Decoder(rig=True, database=db)
    got = {u.name: u.value for m in rig for u in decoder.feed(m)}
    assert got == {f"meas_T_{c}_c": t for c, t in temps.items()}


def test_another_description_loads_strictly_and_round_trips_every_component(r1, tmp_path):
    out = tmp_path / "r1.dbc"
    assert main(["export-dbc", "--gearbox", str(r1), "--out", str(out)]) == 0
    db = cantools.database.load_file(str(out), strict=True)
    ids = ["P", "W", "B1", "B2", "B3", "B4", "oil"]
    names = [m.name for m in db.messages]
    assert [n for n in names if n.startswith(("GBX_", "RIG_"))] == [
        "GBX_TEMP_1", "GBX_TEMP_2", "GBX_WARN", "GBX_TTL_1", "GBX_TTL_2", "GBX_STATUS", "GBX_DM1", "RIG_TC_1",
        "RIG_TC_2",
    ]  # fmt: skip
    assert {n: pgn_of(db.get_message_by_name(n).frame_id) for n in names if n.startswith(("GBX_", "RIG_"))} == {
        "GBX_TEMP_1": 0xFF40, "GBX_TEMP_2": 0xFF41, "GBX_WARN": 0xFF42, "GBX_TTL_1": 0xFF43, "GBX_TTL_2": 0xFF44,
        "GBX_STATUS": 0xFF45, "GBX_DM1": 0xFECA, "RIG_TC_1": 0xFF46, "RIG_TC_2": 0xFF47,
    }  # fmt: skip
    assert "oil (oil sump)" in db.get_message_by_name("GBX_TEMP_2").get_signal_by_name("T_oil").comment
    grs = cantools.database.load_file(str(SHIPPED), strict=True)
    for m in grs.messages:  # the J1939 inputs and DM1 are every gearbox's
        if not m.name.startswith(("GBX_TEMP", "GBX_WARN", "GBX_TTL", "GBX_STATUS", "RIG_")):
            assert db.get_message_by_name(m.name).frame_id == m.frame_id
            assert [(s.name, s.start, s.length, s.scale, s.offset) for s in m.signals] == [
                (s.name, s.start, s.length, s.scale, s.offset) for s in db.get_message_by_name(m.name).signals
            ]
    loaded = dbc.load_dbc(out)
    assert loaded.published_components() == tuple(ids)
    _roundtrip(loaded, ids)
    temp_2 = OutputEncoder(database=loaded).encode({"oil": 90.0}, {}, {}, {})[1]
    assert bytes(temp_2.data)[6:] == b"\xff\xff"  # GBX_TEMP_2: B3, B4, oil; bytes 7-8 are fill
    assert "B1 (" not in db.get_message_by_name("GBX_TEMP_1").get_signal_by_name("T_B1").comment  # no name: id only
    assert dbc.load_dbc(out.read_text(encoding="utf-8")).published_components() == tuple(ids)  # text, too


def test_more_than_32_components_take_several_warning_frames():
    ids = [f"N{i}" for i in range(41)]
    text = generate.generate_dbc(ids)
    db = dbc.load_dbc(text)
    assert db.warn_messages() == ("GBX_WARN_1", "GBX_WARN_2")
    _roundtrip(db, ids)


def test_the_shipped_dbc_is_the_default_everywhere():
    assert dbc.load_dbc() is dbc.shipped()
    assert dbc.load_dbc(SHIPPED).published_components() == dbc.published_components()
    a, b = OutputEncoder(), OutputEncoder(database=SHIPPED)
    args = ({"oil": 80.0}, {"oil": 1}, {"oil": 5.0}, {"counter": 3})
    assert [(f.arbitration_id, bytes(f.data)) for f in a.encode(*args)] == [
        (f.arbitration_id, bytes(f.data)) for f in b.encode(*args)
    ]


def test_a_bad_dbc_is_one_sentence(tmp_path):
    with pytest.raises(dbc.DecodeError, match="cannot be read"):
        dbc.load_dbc(tmp_path / "missing.dbc")
    with pytest.raises(dbc.DecodeError, match="is no valid DBC"):
        dbc.load_dbc("BO_ this is\nnot a DBC")


def test_too_many_components_is_one_sentence_exit_2(monkeypatch, capsys):
    published = tuple(SimpleNamespace(id=f"X{i}") for i in range(generate.MAX_COMPONENTS + 1))
    fake = SimpleNamespace(name="BIG", published=published, names={})
    monkeypatch.setattr("firmware_model.description.load_description", lambda name: fake)
    assert main(["export-dbc", "--gearbox", "BIG"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gearbox-vsensor export-dbc: error: gearbox BIG: 245 published components need")
    assert "\n" not in err and "at most 244 fit" in err


@pytest.mark.parametrize("name", shipped_descriptions())
def test_every_shipped_description_s_dbc_loads_strictly(name, tmp_path, capsys):
    """Every shipped description's generated DBC (no onboard sensor needed: the MM82's too) loads with cantools
    strict=True, carries a temperature, warning level, time to limit and rig signal per component the sensor
    publishes, in the description's order, and the project's loader reads those components back from it: the
    layout the CAN service sends (can_dbc.dbc.for_components of the sensor's components). A derived temperature
    (the MM82's oil.inlet, no node of the onboard network) is not on the bus: the MM82's DBC carried it, every
    later signal one slot off the sensor's frames."""
    from firmware_model.onboard.reduce import published_ids

    d = load_description(name)
    out = tmp_path / f"{name}.dbc"
    assert main(["export-dbc", "--gearbox", name, "--out", str(out)]) == 0
    db = cantools.database.load_file(str(out), strict=True)
    ids = list(published_ids(d))
    assert dbc.for_components(tuple(ids)).published_components() == tuple(ids)
    assert [m.frame_id for m in dbc.for_components(tuple(ids)).database.messages] == [m.frame_id for m in db.messages]
    signals = {s.name for m in db.messages for s in m.signals}
    for c in ids:  # the signal names of docs/can.md: a component id's dot as an underscore
        stem = c.replace(".", "_")
        assert {f"T_{stem}", f"W_{stem}", f"TTL_{stem}", f"TC_{stem}"} <= signals, c
    assert dbc.load_dbc(out).published_components() == tuple(ids)
    _roundtrip(dbc.load_dbc(out), ids)
    # a drive whose torque EEC1 cannot carry (the MM82's rotor, 2.5 MN m) is told so: its inputs come another way
    err = capsys.readouterr().err
    assert ("cannot come over this DBC's J1939 frames" in err) == (d.drive.max_torque_nm > 1.25 * 64255), err


def test_export_dbc_never_writes_over_its_description_and_writes_only_a_dbc(tmp_path, capsys):
    """--out on the description itself, or a name that is no .dbc, is one sentence, exit 2, the description intact
    (it was overwritten with the DBC, which no command could then read)."""
    from firmware_model.parameters import PARAM_DIR

    desc = tmp_path / "my.toml"
    desc.write_text((PARAM_DIR / "R1.toml").read_text())
    before = desc.read_bytes()
    for out, words in ((desc, "a DBC file's name ends in .dbc"), (tmp_path / "x.txt", "ends in .dbc")):
        assert main(["export-dbc", "--gearbox", str(desc), "--out", str(out)]) == 2
        assert words in capsys.readouterr().err
    assert desc.read_bytes() == before
    dbc_like = tmp_path / "my.dbc"
    assert main(["export-dbc", "--gearbox", str(desc), "--out", str(dbc_like)]) == 0
    assert cantools.database.load_file(str(dbc_like)).messages
