"""EXR files (``core.exr``): passes and header attributes written and read back, and no partial file left."""
import os

import numpy as np

from vpl_addon.core.exr import read_header, read_passes, write_passes


def test_exr_round_trip_with_attributes_and_no_partial_file(tmp_path):
    passes = {"Combined": np.random.rand(3, 5, 4).astype(np.float32),
              "Diffuse Direct": np.random.rand(3, 5, 3).astype(np.float32)}
    path = tmp_path / "x.exr"
    write_passes(str(path), passes, {"vplReference": '{"hash": "abc"}'})
    back, header = read_passes(str(path))
    assert header["vplReference"] == read_header(str(path))["vplReference"] == '{"hash": "abc"}'
    for name in passes:
        assert np.array_equal(back[name], passes[name])
    assert os.listdir(tmp_path) == ["x.exr"]
