"""starid.kernels.params.exact_float64: the scalars a kernel takes as one float64 array, each exact."""

import numpy as np
import pytest

from starid.errors import ConfigError
from starid.kernels.params import exact_float64


def test_values_round_trip_with_their_types():
    values = [0.1, -3, np.int64(7), True, False, np.float32(0.25), float("inf"), 2**53]
    out = exact_float64(values, "t")
    assert out.dtype == np.float64 and out.shape == (len(values),)
    assert out[0] == 0.1 and int(out[1]) == -3 and int(out[2]) == 7
    assert out[3] == 1.0 and out[4] == 0.0 and out[5] == 0.25 and np.isinf(out[6]) and int(out[7]) == 2**53


@pytest.mark.parametrize("bad", [2**53 + 1, np.int64(-(2**62) - 1), np.zeros(3)])
def test_refuses_what_float64_does_not_hold(bad):
    with pytest.raises(ConfigError, match="my kernel"):
        exact_float64([1.0, bad], "my kernel")
