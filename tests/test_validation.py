"""Scalar checks (:mod:`hubbeam_ctrl.core.validation`): accepted values come back as floats,
everything else is a one-line ParameterError naming the setting, its range and unit."""

import math

import numpy as np
import pytest

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.validation import check_finite, check_nonnegative, check_positive

CHECKS = {check_positive: "> 0", check_nonnegative: ">= 0", check_finite: None}


@pytest.mark.parametrize("value", [2, 2.5, np.float64(2.5), np.int32(2), np.float32(0.5), 1e300])
@pytest.mark.parametrize("check", list(CHECKS))
def test_accepted_values_come_back_as_float(check, value):
    out = check("x", value, "m")
    assert type(out) is float and out == float(value)


@pytest.mark.parametrize("check,value,ok", [
    (check_positive, 0.0, False), (check_positive, 1e-300, True), (check_positive, -1.0, False),
    (check_nonnegative, 0.0, True), (check_nonnegative, -0.0, True), (check_nonnegative, -1e-300, False),
    (check_finite, -1e300, True), (check_finite, 0.0, True),
])
def test_range_boundaries(check, value, ok):
    if ok:
        assert check("x", value, "s") == value
    else:
        with pytest.raises(ParameterError):
            check("x", value, "s")


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, True, False, None, "3", [1.0], np.array([1.0]),
                                   1 + 0j])
@pytest.mark.parametrize("check", list(CHECKS))
def test_non_numbers_are_rejected(check, value):
    with pytest.raises(ParameterError):
        check("x", value, "s")


@pytest.mark.parametrize("check,bound", list(CHECKS.items()))
def test_message_names_setting_range_unit_and_value(check, bound):
    with pytest.raises(ParameterError) as info:
        check("tau_max", math.nan, "N m")
    text = str(info.value)
    assert text.startswith("tau_max must be a finite number") and "\n" not in text
    assert "[N m]" in text and text.endswith("got nan")
    if bound:
        assert bound in text
    # ParameterError is both the toolbox's error and a ValueError
    assert isinstance(info.value, HubbeamError) and isinstance(info.value, ValueError)
