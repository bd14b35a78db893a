"""The checks and conversions the Python bindings apply to arguments before preCICE sees them."""

from __future__ import annotations

from typing import Any

import numpy as np


def convert(value: Any) -> str:
    """The bindings' ``convert``: str or bytes, anything else is a ``TypeError``."""
    if type(value) is bytes:
        return value.decode()
    if type(value) is str:
        return value
    raise TypeError("Could not convert.")


def check_array_like(argument: Any, argument_name: str, function_name: str) -> None:
    try:
        argument.__len__  # noqa: B018
        argument.__getitem__  # noqa: B018
    except AttributeError:
        raise TypeError(
            f"{function_name} requires array_like input for {argument_name}, but was provided "
            f"the following input type: {type(argument)}"
        ) from None


def as_vertex_ids(vertex_ids: Any) -> np.ndarray:
    ids = np.asarray(vertex_ids)
    if ids.size and ids.dtype.kind not in "iu":
        raise TypeError("an integer is required")
    return ids.astype(np.int64, copy=False).reshape(-1)
