"""The report's pictures fit the site's column, so the page shows their text at 100 %."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.text import Text
from PIL import Image

from agents.evaluation import plots
from agents.evaluation.leaderboard import Panel, Standing, plot_leaderboard


@pytest.fixture
def closed_figures(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """The figures the plotting functions close, kept to read their text afterwards."""
    figures: list[Any] = []
    close = plt.close

    def keep(figure: Any = None) -> None:
        figures.append(figure)
        close(figure)

    monkeypatch.setattr(matplotlib.pyplot, "close", keep)
    return figures


def _text_sizes(figure: Any) -> list[float]:
    return [
        text.get_fontsize()
        for text in figure.findobj(Text)
        if text.get_text().strip() and text.get_visible()
    ]


def _frame(column: int) -> np.ndarray:
    """A 200 x 300 background with a dark box (the "convoy") moved by ``column``."""
    frame = np.full((200, 300, 3), 240, dtype=np.uint8)
    frame[80:120, 50 + 10 * column : 150 + 10 * column] = 30
    return frame


def test_frames_picture_is_the_column_wide_with_text_of_10_pt(
    tmp_path: Path, closed_figures: list[Any]
) -> None:
    captions = [f"t = {2.0 * i:.1f} s\nmargin 1.00" for i in range(6)]
    rows = {
        "zero": ([_frame(i) for i in range(4)], [*captions[:3], "t = 4.6 s, folded\nmargin 0.00"]),
        "dagger_reverse_v1_n2": ([_frame(i) for i in range(6)], captions),
    }
    out = plots.plot_frames(rows, tmp_path / "frames.png", "a title\nits second line")
    assert Image.open(out).size[0] == plots.PAGE_WIDTH_PX == 930
    (figure,) = closed_figures
    sizes = _text_sizes(figure)
    # The two rows' names, 10 captions and the title.
    assert len(sizes) == 13
    assert min(sizes) == plots.FRAME_FONT_PT == 10
    with pytest.raises(ValueError, match="no rows"):
        plots.plot_frames({}, tmp_path / "none.png")
    assert not (tmp_path / "none.png").exists()


def _panel(n: int) -> Panel:
    standings = (
        Standing("lqr", "lqr", 0.91, 0.84, 0.95),
        Standing(f"dagger_reverse_v1_n{n}", "learned", 0.97, 0.92, 0.99),
    )
    return Panel("trailer_env/Reverse-v1", n, "safe_rate", standings, 1.0, 0.91)


@pytest.mark.parametrize(("small", "smallest"), [(False, 9), (True, 8)])
def test_leaderboard_is_the_column_wide_with_text_of_8_pt_or_more(
    tmp_path: Path, closed_figures: list[Any], small: bool, smallest: int
) -> None:
    out = plot_leaderboard([_panel(n) for n in (1, 2, 3)], tmp_path / "board.png", small=small)
    assert Image.open(out).size[0] == 930
    (figure,) = closed_figures
    assert min(_text_sizes(figure)) == smallest
