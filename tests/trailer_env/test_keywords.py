"""The gym.make keywords: one table (MAKE_KEYWORDS, from the settings record), the
generated docs/generated/keywords.md equal to it, and the settings storing each."""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import pytest

from trailer_env.__main__ import main
from trailer_env.settings import (
    MAKE_KEYWORDS,
    EnvSettings,
    keywords_markdown,
    settings_from_kwargs,
)

ROOT = Path(__file__).resolve().parents[2]


def test_the_table_is_the_settings_fields_and_the_signature() -> None:
    names = [name for name, _ in MAKE_KEYWORDS]
    fields = [item.name for item in dataclasses.fields(EnvSettings)]
    assert names == ["n_trailers", *fields]
    accepted = [
        name
        for name, parameter in inspect.signature(settings_from_kwargs).parameters.items()
        if parameter.kind is not inspect.Parameter.VAR_KEYWORD
    ]
    assert sorted(accepted) == sorted(names)
    assert all(meaning and "\n" not in meaning for _, meaning in MAKE_KEYWORDS)


def test_the_generated_page_is_the_table(tmp_path: Path) -> None:
    committed = (ROOT / "docs" / "generated" / "keywords.md").read_text()
    assert committed == keywords_markdown()
    out = tmp_path / "keywords.md"
    assert main(["--keywords", str(out)]) == 0
    assert out.read_text() == committed
    with pytest.raises(SystemExit) as refused:
        main(["--keywords", str(tmp_path / "missing" / "keywords.md")])
    assert refused.value.code == 2


def test_an_unknown_keyword_names_the_table() -> None:
    with pytest.raises(TypeError, match="unexpected keyword argument 'speed'") as error:
        settings_from_kwargs(speed=1.0)
    assert all(name in str(error.value) for name, _ in MAKE_KEYWORDS)


def test_trailer_draw_is_checked_once_and_stored() -> None:
    assert settings_from_kwargs(trailer_draw="row").trailer_draw == "row"
    assert EnvSettings().trailer_draw == "episode"
    with pytest.raises(ValueError, match="trailer_draw"):
        EnvSettings(trailer_draw="column")
    with pytest.raises(TypeError, match="trailer_draw"):
        settings_from_kwargs(trailer_draw=1)  # type: ignore[arg-type]
