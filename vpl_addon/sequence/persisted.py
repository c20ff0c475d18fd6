"""What a sequence saves between runs, as data: its values turned into one JSON tree and a set of named arrays, in
one npz file (``pack``), and back (``unpack``), so that a bake folder on shared farm storage holds numbers, never
code that runs when a bake resumes from it.

The tree holds JSON's own values (None, booleans, integers, strings, finite floats) as they are and every other
value as an object with one tag: ``list``, ``tuple``, ``dict`` (string keys, in their order), ``float`` (a
non-finite one), ``array`` and ``scalar`` (the name of an array, a numpy scalar being a 0-d one), ``record`` with
its ``fields``, or ``ref``: the number of a list, tuple, dict, array or record met before (numbered in the order
the tree meets them), so that a value two fields share comes back shared, as it was. Arrays are stored bit for bit
and read without pickles (``np.load(allow_pickle=False)``): an array of Python objects is refused on both sides.

A record is an instance of one of the types in ``RECORDS``, a fixed table keyed by the type's name: nothing else
is made from a name the file chooses. Each type declares its fields (a dataclass its own; any other class names
them), and ``transient`` the attributes it makes afresh when read (a tracer, a lock); a value holding an attribute
its record does not declare is refused when packed, and a file whose record lacks or adds a field when unpacked.
Each layer's types are registered where they are known without an upward import: the ones below ``sequence``
here, the sequence's own in their modules (``record`` as a class decorator) and a method's in its package.
"""
from __future__ import annotations

import dataclasses
import io
import json
import math
import threading
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..gather.virtual_lights import VirtualLights
from ..lights import AreaLight, EmissiveTriangles, EnvironmentLight, PointLight, SpotLight, SunLight, WorldLight
from ..materials.surface import Surface

TREE = "tree"  # the npz member holding the JSON (header and tree), as UTF-8 bytes


@dataclass(frozen=True)
class Record:
    """A type the tree may hold: its fields, and the attributes it makes afresh (name -> a function of nothing)."""
    kind: type
    fields: tuple[str, ...]
    transient: dict[str, Callable[[], object]]


RECORDS: dict[str, Record] = {}


def record(kind: type | None = None, *, fields: tuple[str, ...] | None = None,
           transient: dict[str, Callable[[], object]] | None = None):
    """Register ``kind`` under its name (a class decorator, bare for a dataclass): its ``fields`` (a dataclass's
    by default) are saved, its ``transient`` attributes made afresh when read. The same class registered again (its
    module imported anew) replaces itself; another class of the same name is a TypeError."""
    def register(kind: type) -> type:
        named = tuple(f.name for f in dataclasses.fields(kind)) if fields is None else tuple(fields)
        held = RECORDS.get(kind.__name__)
        if held is not None and (held.kind.__module__, held.kind.__qualname__) != (kind.__module__,
                                                                                   kind.__qualname__):
            raise TypeError(f"two record types are named {kind.__name__}: {held.kind.__module__} and "
                            f"{kind.__module__}")
        RECORDS[kind.__name__] = Record(kind, named, dict(transient or {}))
        return kind
    return register if kind is None else register(kind)


record(VirtualLights)
record(Surface)
for _light in (PointLight, SpotLight, AreaLight, SunLight):
    record(_light)
record(WorldLight, fields=("constant",))
record(EnvironmentLight, fields=("image", "rotation", "texel_prob", "row_cdf", "col_cdf", "guide", "mean_luminance"))
record(EmissiveTriangles, fields=("triangles", "normals", "radiance", "areas", "total", "cdf", "prob"),
       transient={"_tracer": lambda: None, "_building": threading.Lock})


def pack(value, header: dict) -> bytes:
    """``value`` and the JSON ``header`` (what a reader checks before it reads the value) as the bytes of an npz
    file; TypeError for a value of a type the tree cannot hold."""
    writer = _Writer()
    tree = json.dumps({"header": header, "value": writer.tree(value)}, allow_nan=False, separators=(",", ":"))
    buffer = io.BytesIO()
    np.savez(buffer, **{TREE: np.frombuffer(tree.encode(), np.uint8)}, **writer.arrays)
    return buffer.getvalue()


def unpack(data: bytes) -> tuple[dict, Callable[[], object]]:
    """(header, read): the header ``pack`` wrote, to be checked first, and the function that reads the value;
    ValueError from either for anything but such a file: another format (a pickle is never loaded), damaged bytes,
    a type ``RECORDS`` does not hold or a record of other fields."""
    try:
        loaded = np.load(io.BytesIO(data), allow_pickle=False)
        if isinstance(loaded, np.ndarray):
            raise ValueError("one array, not an npz file")
        with loaded:
            arrays = {name: loaded[name] for name in loaded.files}
        whole = json.loads(arrays.pop(TREE).tobytes().decode())
        header, tree = whole["header"], whole["value"]
    except Exception as err:  # whatever bytes that are not such a file make the zip, zlib, npy or JSON readers raise
        raise ValueError(f"not a saved state: {type(err).__name__}: {err}") from None
    if not isinstance(header, dict):
        raise ValueError("not a saved state: no header")

    def read():
        try:
            return _Reader(arrays).value(tree)
        except (KeyError, TypeError, RecursionError) as err:  # a name or a node of the wrong kind, a tree too deep
            raise ValueError(f"a damaged saved state: {type(err).__name__}: {err}") from None
    return header, read


class _Writer:
    """The tree of a value, its arrays gathered in ``arrays``."""

    def __init__(self):
        self.arrays: dict[str, np.ndarray] = {}
        # id of a list, tuple, dict, array or record met -> its number (each is reachable from the value packed,
        # so no id is reused while it packs)
        self.numbers: dict[int, int] = {}

    def tree(self, value):
        if value is None or type(value) in (bool, int, str):
            return value
        if type(value) is float:
            return value if math.isfinite(value) else {"float": repr(value)}
        if isinstance(value, np.generic):
            return {"scalar": self._array(np.asarray(value))}
        if id(value) in self.numbers:
            return {"ref": self.numbers[id(value)]}
        self.numbers[id(value)] = len(self.numbers)
        if type(value) is np.ndarray:
            return {"array": self._array(value)}
        if type(value) in (list, tuple):
            return {type(value).__name__: [self.tree(v) for v in value]}
        if type(value) is dict:
            if not all(type(k) is str for k in value):
                raise TypeError(f"a dict with keys other than strings: {list(value)[:4]}")
            return {"dict": {k: self.tree(v) for k, v in value.items()}}
        held = RECORDS.get(type(value).__name__)
        if held is None or held.kind is not type(value):
            raise TypeError(f"a {type(value).__qualname__} is not a record type (``persisted.RECORDS``)")
        attributes = vars(value)
        if set(attributes) != {*held.fields, *held.transient}:
            raise TypeError(f"a {type(value).__qualname__} holds {sorted(attributes)}, its record declares "
                            f"{sorted({*held.fields, *held.transient})}")
        return {"record": type(value).__name__, "fields": {f: self.tree(attributes[f]) for f in held.fields}}

    def _array(self, array: np.ndarray) -> str:
        if array.dtype.hasobject:
            raise TypeError(f"an array of Python objects ({array.dtype})")
        name = f"a{len(self.arrays)}"
        self.arrays[name] = array
        return name


_UNFINISHED = object()  # a tuple whose items are being read (a reference to it cannot be resolved yet)


class _Reader:
    """Values from a tree and its arrays, numbered as ``_Writer`` numbered them."""

    def __init__(self, arrays: dict[str, np.ndarray]):
        self.arrays = arrays
        self.made: list = []

    def value(self, node):
        if node is None or type(node) in (bool, int, str, float):
            return node
        if type(node) is not dict or not node:
            raise ValueError(f"a damaged saved state (a node {str(node)[:40]!r})")
        tag, content = next(iter(node.items()))
        if tag == "record" and set(node) == {"record", "fields"}:
            return self._record(content, node["fields"])
        if len(node) != 1:
            raise ValueError(f"a damaged saved state (a node of keys {sorted(node)[:4]})")
        if tag == "float" and content in ("inf", "-inf", "nan"):
            return float(content)
        if tag == "scalar":
            array = self.arrays[content]
            if array.ndim != 0:
                raise ValueError(f"a damaged saved state (scalar {content} of shape {array.shape})")
            return array[()]
        if tag == "ref":
            if type(content) is not int or not 0 <= content < len(self.made) or self.made[content] is _UNFINISHED:
                raise ValueError(f"a damaged saved state (a reference to {content!r})")
            return self.made[content]
        number = len(self.made)
        if tag == "array":
            self.made.append(self.arrays[content])
        elif tag == "list" and type(content) is list:
            self.made.append([])
            self.made[number].extend(self.value(v) for v in content)
        elif tag == "tuple" and type(content) is list:
            self.made.append(_UNFINISHED)
            self.made[number] = tuple([self.value(v) for v in content])
        elif tag == "dict" and type(content) is dict:
            self.made.append({})
            for k, v in content.items():
                self.made[number][k] = self.value(v)
        else:
            raise ValueError(f"a damaged saved state (a node tagged {tag!r})")
        return self.made[number]

    def _record(self, name, fields):
        held = RECORDS.get(name) if type(name) is str else None
        if held is None:
            raise ValueError(f"a saved state holding a {name!r}, which is not a record type of this engine")
        if type(fields) is not dict or set(fields) != set(held.fields):
            raise ValueError(f"a saved state whose {name} has other fields than this engine's: written by another "
                             f"version of VPL GI, or damaged")
        made = held.kind.__new__(held.kind)
        self.made.append(made)
        made.__dict__.update({f: self.value(v) for f, v in fields.items()})
        made.__dict__.update({f: make() for f, make in held.transient.items()})
        return made
