"""Every seed range the project uses, in one place, so that no two uses overlap.

Episode ``i`` of an evaluation starting at seed ``s`` is seeded ``s + i``
(``reset(seed=s + i)``). The ranges are disjoint at the sizes each use plays (test up
to 1,000 episodes, tuning and fresh up to 5,000, the check 20,000, validation and
selection 10,000), so tuning, model selection and training never see a test start.
"""

from __future__ import annotations

#: First seed of the test episodes: every reported table (1000..1099 by default).
TEST_SEED = 1000
#: First seed of the tuning episodes used to size scenes (2000..2199).
TUNING_SEED = 2000
#: First seed of the fresh episodes a reported figure is re-checked on (7000..7199).
FRESH_SEED = 7000
#: First seed of the larger check (1,000 episodes, 30000..30999) of a figure near its target.
CHECK_SEED = 30_000
#: First seed of the validation episodes evaluated during training (best-model choice).
VALIDATION_SEED = 50_000
#: First seed of the selection episodes that pick the committed seed among training seeds.
SELECTION_SEED = 60_000
#: First seed of imitation's training episodes (one block of 10,000 per training seed).
TRAINING_SEED = 100_000
