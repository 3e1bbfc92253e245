import math

import numpy as np
import pytest

from starid import ConfigError
from starid.params import check_choice, check_flag, check_number, check_whole


def test_check_number_bounds():
    check_number("x", 0.0, lo=0)
    check_number("x", np.float32(1.0), lo=0, hi=1)
    for value, kwargs in [(0.0, {"lo": 0, "lo_open": True}), (90.0, {"hi": 90, "hi_open": True}),
                          (math.nan, {}), (math.inf, {}), (True, {}), ("1", {}), (-1e-9, {"lo": 0})]:
        with pytest.raises(ConfigError, match="x must be a finite number"):
            check_number("x", value, **kwargs)


def test_check_whole_flag_choice():
    check_whole("n", np.int64(3), 2, 3)
    for value in (1, 4, 3.0, True):
        with pytest.raises(ConfigError, match="n must be an integer >= 2 and <= 3"):
            check_whole("n", value, 2, 3)
    check_flag("f", np.bool_(True))
    with pytest.raises(ConfigError, match="f must be True or False"):
        check_flag("f", 1)
    check_choice("c", "a", ("a", "b"))
    with pytest.raises(ConfigError, match=r"c must be one of \('a', 'b'\)"):
        check_choice("c", "z", ("a", "b"))
