"""Training options: one record each (:class:`~agents.algorithms.options.base.TrainingOption`).

:data:`TRAINING_OPTIONS` is the one table of them. The command line
(:mod:`agents.commands.train`) adds every record's flags and reads them back, the run's
configuration (:class:`agents.training.config.TrainConfig`) checks each against the run and
writes its part of the run record, the recipe's name (:func:`agents.algorithms.recipes.recipe_name`)
takes its tag, a resumed run is held to the options it was recorded with, and the SB3
trainer lets each set its environment up and add its callbacks. Adding an option is one
module here (a ``TrainingOption`` subclass) plus its entry in :data:`TRAINING_OPTIONS`.
"""

from __future__ import annotations

from collections.abc import Mapping

from agents.algorithms.options.base import OptionError, TrainingOption
from agents.algorithms.options.fine_tune import FineTune
from agents.algorithms.options.shaping import Shaping
from agents.algorithms.options.start_curriculum import StartCurriculum
from agents.algorithms.options.start_replay import StartReplay

__all__ = [
    "TRAINING_OPTIONS",
    "FineTune",
    "OptionError",
    "Shaping",
    "StartCurriculum",
    "StartReplay",
    "TrainingOption",
    "recorded_options",
]

#: Every training option, in the order their tags follow the recipe's name.
TRAINING_OPTIONS: tuple[type[TrainingOption], ...] = (
    Shaping,
    StartCurriculum,
    StartReplay,
    FineTune,
)


def recorded_options(record: Mapping[str, object]) -> tuple[TrainingOption, ...]:
    """The options a run record (``config.json``, a model card) holds.

    Raises:
        ValueError: If an option's part is malformed, naming its key.
    """
    found = (option.from_record(record) for option in TRAINING_OPTIONS)
    return tuple(option for option in found if option is not None)
