"""The orders in which :class:`~agents.policies.convoy_encoder.ConvoyEncoder` may read the
trailers (its ``direction``), kept where nothing imports torch so that commands can
validate the option before a model is built."""

from __future__ import annotations

#: From the cart to the last trailer (the default, every model saved before the option),
#: from the last trailer to the cart, or both passes side by side.
CONVOY_DIRECTIONS = ("cart_first", "tail_first", "both")


def check_direction(name: str, value: object) -> str:
    """``value`` as a direction of :data:`CONVOY_DIRECTIONS` (the option called ``name``).

    Raises:
        TypeError: If it is not a str.
        ValueError: If it is not one of the directions.
    """
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a str, got {type(value).__name__}")
    if value not in CONVOY_DIRECTIONS:
        raise ValueError(f"{name} must be one of {CONVOY_DIRECTIONS}, got {value!r}")
    return value
