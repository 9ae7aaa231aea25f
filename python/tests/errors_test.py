# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""The package imports and C++ exceptions arrive as the documented Python types."""
import re

import pytest

import ds3d


def test_version_is_semver():
    assert re.fullmatch(r"\d+\.\d+\.\d+", ds3d.__version__)


@pytest.mark.parametrize(
    "kind, exc",
    [("invalid_argument", ValueError), ("io", RuntimeError), ("numerical", RuntimeError)],
)
def test_exception_mapping(kind, exc):
    with pytest.raises(exc, match="boom 42"):
        ds3d._ds3d._raise_for_test(kind, "boom 42")


def test_unknown_kind_is_value_error_naming_value():
    with pytest.raises(ValueError, match="got 'nope'"):
        ds3d._ds3d._raise_for_test("nope", "x")
