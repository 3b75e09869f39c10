"""The orders in which :class:`~agents.policies.convoy_encoder.ConvoyEncoder` may read the
trailers (its ``direction``), kept where nothing imports torch so that commands can
validate the option before a model is built."""

from __future__ import annotations

#: From the cart to the last trailer (the default, every model saved before the option),
#: from the last trailer to the cart, or both passes side by side.
CONVOY_DIRECTIONS = ("cart_first", "tail_first", "both")
