"""A sequence's saved values as JSON and arrays (``sequence.persisted``): exact round trips, shared values shared,
and nothing made that the fixed table of record types does not name."""
import io
import json
import pickle

import numpy as np
import pytest

from vpl_addon.gather.virtual_lights import VirtualLights
from vpl_addon.lights import EmissiveTriangles
from vpl_addon.sequence.persisted import RECORDS, TREE, pack, record, unpack


def roundtrip(value, header=None):
    read_header, read = unpack(pack(value, header or {}))
    assert read_header == (header or {})
    return read()


def lights(n=3):
    rng = np.random.default_rng(1)
    return VirtualLights(rng.random((n, 3)), rng.random((n, 3)), rng.random((n, 3)), np.arange(n, dtype=np.int32),
                         np.zeros(n, np.int8), np.arange(n, dtype=np.int64))


def test_values_come_back_exactly_with_their_types_order_and_sharing():
    shared = np.array([0.1, -0.0, np.nan, np.inf, 5e-324])
    placed = lights()
    value = {"z": [1, True, None, "s", 0.1, -0.0, float("inf"), float("nan"), 2 ** 127 + 3],
             "a": (np.float32(0.3), np.int64(-7), np.bool_(True)),
             "arrays": [shared, shared, np.asfortranarray(np.arange(6.0).reshape(2, 3)), np.zeros((0, 3), np.int32)],
             "records": [placed, placed], "rng": np.random.default_rng(5).bit_generator.state}
    back = roundtrip(value, {"format": 1})
    assert list(back) == ["z", "a", "arrays", "records", "rng"]  # the order of the keys
    assert back["z"][:6] == [1, True, None, "s", 0.1, -0.0] and str(back["z"][5]) == "-0.0"
    assert back["z"][6] == float("inf") and np.isnan(back["z"][7]) and back["z"][8] == 2 ** 127 + 3
    assert [type(v) for v in back["z"][:5]] == [int, bool, type(None), str, float]
    assert type(back["a"]) is tuple and [type(v) for v in back["a"]] == [np.float32, np.int64, np.bool_]
    assert back["a"][0] == np.float32(0.3)
    first, again, fortran, empty = back["arrays"]
    assert first is again and first.tobytes() == shared.tobytes()  # bit for bit, and one array as it was
    assert fortran.flags.f_contiguous and np.array_equal(fortran, value["arrays"][2])
    assert empty.shape == (0, 3) and empty.dtype == np.int32
    one, other = back["records"]
    assert one is other and type(one) is VirtualLights
    for name in ("position", "normal", "intensity", "bounce", "kind", "path"):
        got, want = getattr(one, name), getattr(placed, name)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), name
    generator = np.random.default_rng(0)
    generator.bit_generator.state = back["rng"]
    assert generator.random() == np.random.default_rng(5).random()


def test_a_record_makes_its_transient_attributes_afresh():
    """An emissive light's lazily built tracer and its lock are not saved: they are made again when read."""
    glow = EmissiveTriangles(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float), np.array([[0, 0, 1.0]]),
                             np.array([[2.0, 2.0, 2.0]]))
    glow._tracer = object()  # as if built: a value the tree cannot hold, and need not
    back = roundtrip(glow)
    assert back._tracer is None and back._building.acquire(blocking=False)
    assert back.total == glow.total and back.cdf.tobytes() == glow.cdf.tobytes()


@pytest.mark.parametrize("value, message", [
    (object(), "not a record type"),
    ({1: "a"}, "keys other than strings"),
    (np.array([None, 1], object), "Python objects"),
    ({1, 2}, "not a record type"),
])
def test_a_value_the_tree_cannot_hold_is_refused_when_packed(value, message):
    with pytest.raises(TypeError, match=message):
        pack(value, {})


def test_a_record_holding_an_attribute_it_does_not_declare_is_refused_when_packed():
    placed = lights()
    placed.extra = 1
    with pytest.raises(TypeError, match="its record declares"):
        pack(placed, {})


def test_another_class_of_a_registered_name_is_refused_and_the_same_class_replaces_itself():
    from vpl_addon.gather import virtual_lights
    held = RECORDS["VirtualLights"]

    class VirtualLights:  # noqa: F811 (the clash is the point)
        pass
    with pytest.raises(TypeError, match="two record types are named VirtualLights"):
        record(VirtualLights, fields=())
    assert RECORDS["VirtualLights"] is held
    assert record(virtual_lights.VirtualLights) is virtual_lights.VirtualLights  # as when its module is imported anew
    assert RECORDS["VirtualLights"] == held and RECORDS["VirtualLights"] is not held


def npz(tree, save=np.savez, **arrays) -> bytes:
    """An npz file of ``tree`` (JSON) and ``arrays`` as another program could write it."""
    buffer = io.BytesIO()
    save(buffer, **{TREE: np.frombuffer(json.dumps({"header": {}, "value": tree}).encode(), np.uint8)}, **arrays)
    return buffer.getvalue()


def damaged_stream() -> bytes:
    """A compressed npz whose array's deflate stream is damaged (zlib, not the zip reader, finds it)."""
    data = bytearray(npz({"array": "a0"}, np.savez_compressed, a0=np.random.default_rng(0).random(1000)))
    at = data.find(b"a0.npy") + 30  # past the member's name and its zip64 field, inside its data
    data[at:at + 8] = bytes(8)
    return bytes(data)


@pytest.mark.parametrize("data", [
    pickle.dumps({"a": 1}), b"", b"PK\x03\x04damaged", np.lib.format.MAGIC_PREFIX + b"\x01\x00",
    npz({"record": "Popen", "fields": {}}),  # a type the table does not hold
    npz({"record": "VirtualLights", "fields": {"position": None}}),  # fields of another layout
    npz({"list": [{"ref": 1}]}),  # a reference to nothing
    npz({"array": "a9"}),
    npz({"tuple": [{"ref": 0}]}),  # a tuple inside itself
    npz({"scalar": "a0"}, a0=np.zeros(2)),
    npz({"dict": [1, 2]}), npz({"float": "1e999x"}), npz([1]), npz({"list": []}, a0=np.array([{"x": 1}], object)),
    damaged_stream(),
])
def test_anything_but_a_packed_value_is_a_value_error(data):
    with pytest.raises(ValueError):
        unpack(data)[1]()
