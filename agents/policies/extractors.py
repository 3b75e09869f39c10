"""The SB3 features extractors the project ships, by name (nothing here imports torch).

Hyperparameter files name them in ``policy_kwargs`` (``features_extractor_class=
ConvoyEncoder``, :func:`agents.training.config.parse_policy_kwargs`), and the safe loader
rebuilds a saved model's ``policy_kwargs`` from them instead of unpickling the class
(:func:`agents.artifacts.sb3_zip.safe_custom_objects` takes :func:`feature_extractors`).
Only classes of this table are ever built from a file.
"""

from __future__ import annotations

#: Names of the shipped features extractors (a ``policy_kwargs`` string may use them).
FEATURE_EXTRACTORS = ("ConvoyEncoder",)


def feature_extractors() -> dict[str, type]:
    """Name -> class of every shipped features extractor (imports torch and SB3)."""
    from agents.policies.convoy_encoder import ConvoyEncoder

    return {"ConvoyEncoder": ConvoyEncoder}


def feature_extractor(name: str) -> type:
    """The shipped features extractor called ``name``.

    Raises:
        ValueError: Naming the shipped ones, if there is none of that name.
    """
    if name not in FEATURE_EXTRACTORS:
        raise ValueError(
            f"unknown features extractor {name!r}; shipped: {list(FEATURE_EXTRACTORS)}"
        )
    return feature_extractors()[name]
