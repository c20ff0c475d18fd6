"""``core.color``'s sRGB transfer functions: IEC 61966-2-1's values, each the other's inverse."""
import numpy as np

from vpl_addon.core.color import linear_to_srgb, srgb_to_linear


def test_srgb_encoding_has_the_standards_values_and_inverts_the_decoding():
    assert np.allclose(linear_to_srgb(np.array([0.0, 0.0031308, 0.18, 1.0])),
                       [0.0, 0.04045, 0.46135612, 1.0], atol=1e-5)
    x = np.linspace(0.0, 1.0, 1001)
    assert np.allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)
