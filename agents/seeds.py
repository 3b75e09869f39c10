"""Every seed range the project uses, in one place, so that no two uses overlap.

Episode ``i`` of an evaluation starting at seed ``s`` is seeded ``s + i``
(``reset(seed=s + i)``). The ranges are disjoint for up to 10,000 episodes each, so
tuning, model selection and training never see a test start.
"""

from __future__ import annotations

#: First seed of the test episodes: every reported table (1000..1099 by default).
TEST_SEED = 1000
#: First seed of the tuning episodes used to size scenes (2000..2199).
TUNING_SEED = 2000
#: First seed of the fresh episodes a reported figure is re-checked on (7000..7199).
FRESH_SEED = 7000
#: First seed of the validation episodes evaluated during training (best-model choice).
VALIDATION_SEED = 50_000
#: First seed of the selection episodes that pick the committed seed among training seeds.
SELECTION_SEED = 60_000
#: First seed of imitation's training episodes (one block of 10,000 per training seed).
TRAINING_SEED = 100_000
