"""Pixel checks of the convoy renderer (trailer_env.rendering), independent of the envs."""

from __future__ import annotations

import math
import os
import sys

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before pygame is imported anywhere
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
pytest.importorskip("pygame")

from dynamics import ConvoyParams, body_poses
from trailer_env.rendering import (
    AMBER,
    BACKGROUND,
    GREEN,
    INK,
    MASS,
    RED,
    TARGET,
    ConvoyRenderer,
    Marker,
    RenderFrame,
    main,
    margin_colour,
)

WIDTH, HEIGHT = 320, 240


def make_frame(
    params: ConvoyParams, theta: float = 0.0, eta: float = 0.0, margin: float = 1.0, **extra: object
) -> RenderFrame:
    """A straight convoy with the cart's axle midpoint at the origin."""
    xs, ys, thetas = body_poses(params.l, 0.0, 0.0, theta, np.zeros(params.n_trailers))
    return RenderFrame(
        xs=xs,
        ys=ys,
        thetas=thetas,
        mass_xy_body=(params.b, eta),
        singular_margin=margin,
        path=np.array([[-2.0, 0.1], [-1.0, 0.05], [0.0, 0.0]]),
        **extra,  # type: ignore[arg-type]
    )


def draw(params: ConvoyParams, frame: RenderFrame, **kwargs: object) -> np.ndarray:
    renderer = ConvoyRenderer(params, render_mode="rgb_array", width=WIDTH, height=HEIGHT, **kwargs)  # type: ignore[arg-type]
    pixels = renderer.draw(frame)
    renderer.close()
    assert pixels is not None
    return pixels


def colour_mask(pixels: np.ndarray, colour: tuple[int, int, int], tolerance: int = 0) -> np.ndarray:
    return np.abs(pixels.astype(int) - np.array(colour)).max(axis=-1) <= tolerance


@pytest.mark.parametrize("n", [0, 1, 3])
def test_frame_shape_dtype_and_background(n: int) -> None:
    params = ConvoyParams(n_trailers=n)
    pixels = draw(params, make_frame(params, theta=0.3))
    assert pixels.shape == (HEIGHT, WIDTH, 3)
    assert pixels.dtype == np.uint8
    assert tuple(pixels[0, -1]) == BACKGROUND  # top-right corner: no text, no scale bar
    assert tuple(pixels[-1, -1]) == BACKGROUND
    assert (~colour_mask(pixels, BACKGROUND)).sum() > 500  # something was drawn


def test_cart_drawn_at_image_centre_when_camera_centred_on_it() -> None:
    params = ConvoyParams(n_trailers=0)  # the camera centres on the mean axle = the cart's
    pixels = draw(params, make_frame(params))
    centre = pixels[HEIGHT // 2 - 2 : HEIGHT // 2 + 3, WIDTH // 2 - 2 : WIDTH // 2 + 3]
    assert not colour_mask(centre, BACKGROUND).any()


def mass_centroid(pixels: np.ndarray) -> tuple[float, float]:
    rows, cols = np.nonzero(colour_mask(pixels, MASS))
    assert len(rows) > 10
    return float(rows.mean()), float(cols.mean())


def test_mass_moves_with_eta_to_the_left_of_the_heading() -> None:
    params = ConvoyParams(n_trailers=0)
    renderer = ConvoyRenderer(params, render_mode="rgb_array", width=WIDTH, height=HEIGHT)
    ppm = renderer.pixels_per_metre
    left = renderer.draw(make_frame(params, eta=0.25))
    right = renderer.draw(make_frame(params, eta=-0.25))
    assert left is not None and right is not None
    # Heading +x (rightwards): the left of the heading is up on screen (smaller row).
    row_left, col_left = mass_centroid(left)
    row_right, col_right = mass_centroid(right)
    assert row_left == pytest.approx(HEIGHT / 2 - 0.25 * ppm, abs=2.0)
    assert row_right == pytest.approx(HEIGHT / 2 + 0.25 * ppm, abs=2.0)
    assert col_left == pytest.approx(WIDTH / 2 + params.b * ppm, abs=2.0)
    assert col_right == pytest.approx(col_left, abs=1.0)
    # The frames differ only around the rail (x = b, |y| <= s_max plus the mass radius).
    rows, cols = np.nonzero(np.any(left != right, axis=-1))
    assert len(rows) > 0
    assert np.abs(cols - (WIDTH / 2 + params.b * ppm)).max() <= 0.12 * ppm + 2
    assert np.abs(rows - HEIGHT / 2).max() <= (params.s_max + 0.1) * ppm + 2
    # Heading +y (up): the left of the heading is screen-left.
    up = renderer.draw(make_frame(params, theta=math.pi / 2, eta=0.25))
    assert up is not None
    row_up, col_up = mass_centroid(up)
    assert col_up == pytest.approx(WIDTH / 2 - 0.25 * ppm, abs=2.0)
    assert row_up == pytest.approx(HEIGHT / 2 - params.b * ppm, abs=2.0)


def test_singular_margin_colours_bodies_red_only_inside_the_band() -> None:
    params = ConvoyParams(n_trailers=3)
    singular = draw(params, make_frame(params, margin=0.0))
    regular = draw(params, make_frame(params, margin=1.0))
    assert colour_mask(singular, RED, tolerance=30).sum() > 1000
    assert colour_mask(regular, RED, tolerance=30).sum() == 0
    assert colour_mask(regular, GREEN, tolerance=10).sum() > 1000
    assert margin_colour(0.0, 0.3) == RED
    assert margin_colour(0.3, 0.3) == AMBER
    assert margin_colour(1.0, 0.3) == GREEN
    assert margin_colour(2.0, 0.3) == GREEN  # clipped


def test_scale_bar_has_the_length_it_claims() -> None:
    params = ConvoyParams(n_trailers=1)
    renderer = ConvoyRenderer(params, render_mode="rgb_array", width=WIDTH, height=HEIGHT)
    pixels = renderer.draw(make_frame(params))
    assert pixels is not None
    assert renderer.scale_bar_metres in (0.1, 0.2, 0.5, 1.0, 2.0, 5.0)
    corner = colour_mask(pixels[-30:, : WIDTH // 2], INK)
    longest_row = corner.sum(axis=1).max()
    expected = round(renderer.scale_bar_metres * renderer.pixels_per_metre)
    assert expected > 20
    assert abs(longest_row - expected) <= 3


def test_targets_are_drawn() -> None:
    params = ConvoyParams(n_trailers=1)
    plain = draw(params, make_frame(params))
    assert colour_mask(plain, TARGET, tolerance=20).sum() == 0
    dock = draw(params, make_frame(params, markers=(Marker("pose", -1.0, 1.2, 0.0),)))
    heading = draw(params, make_frame(params, markers=(Marker("arrow", 0.0, 0.0, -math.pi / 2),)))
    assert colour_mask(dock, TARGET, tolerance=20).sum() > 50
    rows, _ = np.nonzero(colour_mask(heading, TARGET, tolerance=20))
    assert len(rows) > 50
    assert rows.mean() > HEIGHT / 2  # the arrow points down the screen (heading -pi/2)


def test_text_overlay_changes_the_top_left_corner() -> None:
    params = ConvoyParams(n_trailers=1)
    renderer = ConvoyRenderer(params, render_mode="rgb_array", width=WIDTH, height=HEIGHT)
    if renderer._font is None:
        pytest.skip("pygame.font unavailable")
    blank = renderer.draw(make_frame(params))
    texted = renderer.draw(make_frame(params, text="step 3\nreward 1.0"))
    assert blank is not None and texted is not None
    assert np.any(blank[:40, :100] != texted[:40, :100])


def test_determinism() -> None:
    params = ConvoyParams(n_trailers=2)
    marker = Marker("pose", 0.0, 1.0, 0.5)
    frame = make_frame(params, theta=0.7, eta=0.1, margin=0.2, markers=(marker,), text="x")
    renderer = ConvoyRenderer(params, render_mode="rgb_array", width=WIDTH, height=HEIGHT)
    first, second = renderer.draw(frame), renderer.draw(frame)
    assert first is not None and second is not None
    np.testing.assert_array_equal(first, second)
    np.testing.assert_array_equal(first, draw(params, frame))


def test_bad_arguments() -> None:
    params = ConvoyParams(n_trailers=1)
    with pytest.raises(ValueError, match="render_mode"):
        ConvoyRenderer(params, render_mode="ansi")
    renderer = ConvoyRenderer(params, render_mode="rgb_array")
    with pytest.raises(ValueError, match="shape"):
        renderer.draw(make_frame(ConvoyParams(n_trailers=2)))


def test_missing_pygame_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pygame", None)
    with pytest.raises(ImportError, match=r"trailer-env\[rendering\]"):
        ConvoyRenderer(ConvoyParams(), render_mode="rgb_array")


def test_human_mode_with_dummy_video_driver() -> None:
    params = ConvoyParams(n_trailers=1)
    renderer = ConvoyRenderer(params, render_mode="human", width=WIDTH, height=HEIGHT, fps=1000)
    assert renderer.draw(make_frame(params)) is None
    assert renderer.draw(make_frame(params, eta=0.2)) is None
    import pygame

    pygame.event.post(pygame.event.Event(pygame.QUIT))  # the user closes the window
    assert renderer.draw(make_frame(params)) is None
    assert renderer.user_closed
    assert not pygame.display.get_init()
    assert renderer.draw(make_frame(params)) is None  # later frames are dropped quietly
    renderer.close()


def test_example_script_writes_a_png(tmp_path: os.PathLike[str]) -> None:
    out = os.path.join(tmp_path, "example.png")
    main(["--out", out, "--steps", "20"])
    with open(out, "rb") as handle:
        assert handle.read(8) == b"\x89PNG\r\n\x1a\n"
    # It is a real frame: the same pixels as rendering the same rollout of Reverse-v0.
    import gymnasium as gym
    import pygame

    from trailer_env.controllers import LQRController

    env = gym.make("trailer_env/Reverse-v0", n_trailers=3, render_mode="rgb_array")
    controller = LQRController.from_env(env)
    obs, _ = env.reset(seed=1003)
    for _ in range(20):
        obs, *_ = env.step(controller(obs))
    saved = pygame.surfarray.array3d(pygame.image.load(out)).transpose(1, 0, 2)
    np.testing.assert_array_equal(saved, env.render())
