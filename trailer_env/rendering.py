"""Top-down pygame picture of the convoy, shared by every environment's ``render()``.

pygame is optional (``pip install trailer-env[rendering]``): it is imported only when a
:class:`ConvoyRenderer` is built, so the environments work without it.

Colour map of the singular margin (:func:`margin_colour`): bodies and hitch rods are green
(:data:`GREEN`) at margin 1, fade linearly to amber (:data:`AMBER`) at ``singular_band`` and
from amber to red (:data:`RED`) at margin 0, so red always means "inside the singular band".
The moving mass is blue, a dock target purple, the cart's past path grey.

Run ``python -m trailer_env.rendering --out docs/img/render_example.png`` for a real frame
(Reverse-v0, three trailers, the LQR baseline steering).
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from dynamics import ConvoyParams, body_poses
from dynamics.columns import ALPHA, ETA, XI, theta_column, x_column, y_column
from trailer_env.randomize import PARAMETERS

if TYPE_CHECKING:
    from trailer_env.core import ConvoyCore

RGB = tuple[int, int, int]
BACKGROUND: RGB = (245, 245, 240)
GREEN: RGB = (70, 170, 90)
AMBER: RGB = (240, 170, 30)
RED: RGB = (220, 40, 40)
MASS: RGB = (40, 80, 210)
TARGET: RGB = (150, 70, 200)
PATH: RGB = (160, 160, 160)
INK: RGB = (35, 35, 35)  # wheels, outlines, text, scale bar
RAIL: RGB = (90, 90, 90)
RENDER_MODES = ("human", "rgb_array")
_MAX_PIXEL = 16000.0  # gfxdraw takes 16-bit coordinates: keep far-away points representable


MARKER_KINDS = ("pose", "arrow")


@dataclass(frozen=True)
class Marker:
    """A scene's extra drawn over the floor: a target pose or a direction.

    Attributes:
        kind: "pose" (the outline of a trailer and its rod at (x, y), facing ``heading``,
            e.g. a dock) or "arrow" (an arrow from (x, y) along ``heading``, e.g. a target
            heading drawn from the cart's axle).
        x, y, heading: World position (m) and direction (rad).
        colour: RGB of the outline or arrow.
    """

    kind: str
    x: float
    y: float
    heading: float
    colour: RGB = TARGET

    def __post_init__(self) -> None:
        if self.kind not in MARKER_KINDS:
            raise ValueError(f"marker kind must be one of {MARKER_KINDS}, got {self.kind!r}")


@dataclass(frozen=True)
class RenderFrame:
    """Everything one picture shows; the environment builds it from its state.

    Attributes:
        xs, ys, thetas: Axle-midpoint positions (m) and headings (rad) of the bodies, ``(n+1,)``,
            index 0 = cart (as returned by :func:`dynamics.body_poses`).
        mass_xy_body: Moving mass (xi, eta) in the cart's frame from its axle midpoint
            (xi forward, eta to the left).
        singular_margin: Distance to the singular set in [0, 1]; 0 = singular.
        path: ``(k, 2)`` past positions of the cart's axle midpoint.
        markers: The scene's targets (:class:`Marker`), drawn under the convoy.
        text: Overlay in the top-left corner; lines split on newlines.
    """

    xs: np.ndarray
    ys: np.ndarray
    thetas: np.ndarray
    mass_xy_body: tuple[float, float]
    singular_margin: float
    path: np.ndarray
    markers: tuple[Marker, ...] = ()
    text: str = ""


class PathTrace:
    """The last ``length`` positions of each of ``batch`` carts, held as one ring buffer.

    Recording and clearing work on the whole batch at once, so a vector env that renders
    keeps its paths without a Python loop over environments.
    """

    def __init__(self, batch: int, length: int = 2000) -> None:
        self.length = length
        self._points = np.zeros((batch, length, 2))
        self._count = np.zeros(batch, dtype=np.int64)
        self._head = np.zeros(batch, dtype=np.int64)  # index the next point goes to

    def clear(self, rows: np.ndarray | slice = slice(None)) -> None:
        """Forget the paths of ``rows`` (all by default)."""
        self._count[rows] = 0
        self._head[rows] = 0

    def record(self, xy: np.ndarray, rows: np.ndarray | slice = slice(None)) -> None:
        """Append one position ``xy`` (len(rows), 2) to the paths of ``rows``."""
        indices = np.arange(self._count.size)[rows]
        self._points[indices, self._head[indices]] = xy
        self._head[indices] = (self._head[indices] + 1) % self.length
        self._count[indices] = np.minimum(self._count[indices] + 1, self.length)

    def path(self, i: int) -> np.ndarray:
        """Row ``i``'s path, oldest point first, ``(k, 2)``."""
        count, head = int(self._count[i]), int(self._head[i])
        order = (head - count + np.arange(count)) % self.length
        return self._points[i, order].copy()

    def __len__(self) -> int:
        """Points held for row 0 (the single env's path)."""
        return int(self._count[0])


def core_frame(core: ConvoyCore, i: int, path: np.ndarray) -> RenderFrame:
    """The picture of row ``i`` of a :class:`~trailer_env.core.ConvoyCore` tracking its pose."""
    n = core.n
    z = core.z[i]
    length = float(core.param_values[i, PARAMETERS.index("l")])  # the episode's (randomize)
    xs, ys, thetas = body_poses(
        length, z[x_column(n)], z[y_column(n)], z[theta_column(n)], z[ALPHA : ALPHA + n]
    )
    return RenderFrame(
        xs=xs,
        ys=ys,
        thetas=thetas,
        mass_xy_body=(float(core.act[i, XI]), float(core.act[i, ETA])),
        singular_margin=float(core.singular_margin[i]),
        path=path,
        markers=core.render_markers(i),
        text=f"u = {z[0]:+.2f} m/s   margin = {core.singular_margin[i]:.2f}",
    )


def make_renderer(core: ConvoyCore, render_mode: str, fps: int) -> ConvoyRenderer:
    """A renderer for the scene of ``core`` (its geometry, singular band and view size)."""
    return ConvoyRenderer(
        core.params,
        render_mode=render_mode,
        singular_band=core.settings.singular_band,
        fps=fps,
        view_size=core.render_view_size(),
    )


def margin_colour(margin: float, singular_band: float = 0.3) -> RGB:
    """Colour of bodies and rods: green at 1, amber at ``singular_band``, red at 0."""
    margin = min(max(float(margin), 0.0), 1.0)
    if margin >= singular_band:
        low, high, t = AMBER, GREEN, (margin - singular_band) / max(1.0 - singular_band, 1e-9)
    else:
        low, high, t = RED, AMBER, margin / singular_band
    red, green, blue = (round(lo + t * (hi - lo)) for lo, hi in zip(low, high, strict=True))
    return red, green, blue


def _nice_length(upper: float) -> float:
    """Largest 1, 2 or 5 times a power of ten not above ``upper``."""
    power = 10.0 ** math.floor(math.log10(upper))
    return max(step * power for step in (1.0, 2.0, 5.0) if step * power <= upper)


def _private_runtime_dir() -> None:
    """Give SDL a private ``XDG_RUNTIME_DIR`` when the session has none.

    SDL's display probe prints "XDG_RUNTIME_DIR is invalid or not set" to standard error
    (from C, so Python cannot filter it) on machines without a desktop session (ssh, CI,
    containers). Without a session there is no Wayland or audio socket to find there, so
    an empty directory of our own (mode 0700, as the specification asks) changes nothing
    but the noise; a valid one is left alone.
    """
    current = os.environ.get("XDG_RUNTIME_DIR", "")
    if not (current and os.path.isdir(current)):
        os.environ["XDG_RUNTIME_DIR"] = tempfile.mkdtemp(prefix="trailer-env-runtime-")


class ConvoyRenderer:
    """Draws :class:`RenderFrame` objects into a window or an RGB array.

    Args:
        params: Convoy geometry (n_trailers, l, a, b, s_max are used).
        render_mode: "human" (a pygame window ticking at ``fps``) or "rgb_array".
        width, height: Picture size in pixels.
        singular_band: Margin below which bodies turn from amber to red.
        fps: Frame rate of the human window.
        view_size: Metres shown across the smaller image side; default fits the convoy.

    Raises:
        ValueError: For an unknown render mode or a non-positive size.
        ImportError: If pygame is not installed.
    """

    def __init__(
        self,
        params: ConvoyParams,
        *,
        render_mode: str,
        width: int = 600,
        height: int = 600,
        singular_band: float = 0.3,
        fps: int = 20,
        view_size: float | None = None,
    ) -> None:
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES}, got {render_mode!r}")
        if width <= 0 or height <= 0 or (view_size is not None and not view_size > 0):
            raise ValueError("width, height and view_size must be positive")
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        try:
            import pygame
            import pygame.gfxdraw
        except ImportError as error:
            raise ImportError(
                "rendering needs pygame: pip install 'trailer-env[rendering]'"
            ) from error
        self._pg: Any = pygame
        self.params, self.render_mode, self.fps = params, render_mode, fps
        self.width, self.height, self.singular_band = width, height, singular_band
        l = params.l
        # A straight convoy spans n rods plus a body at each end; the rest leaves room for curves.
        nose = max(abs(params.a) + 0.3 * l, abs(params.b) + 0.1 * l, params.s_max)
        self.view_size = view_size or (params.n_trailers + 1) * l + 2.0 * nose + l
        self.pixels_per_metre = min(width, height) / self.view_size
        self.scale_bar_metres = _nice_length(self.view_size / 4.0)
        self._surface = pygame.Surface((width, height))
        self._window: Any = None
        self._clock: Any = None
        self.user_closed = False
        try:
            pygame.font.init()
            self._font: Any = pygame.font.Font(None, max(14, height // 32))
        except Exception:  # no SDL_ttf or default font: draw without text
            self._font = None

    # -- geometry -------------------------------------------------------------------------------
    def _to_pixels(self, points: np.ndarray) -> np.ndarray:
        """World points ``(..., 2)`` to screen pixels (y up in the world, down on screen)."""
        offset = (np.asarray(points, dtype=np.float64) - self._centre) * self.pixels_per_metre
        pixels = np.stack([self.width / 2 + offset[..., 0], self.height / 2 - offset[..., 1]], -1)
        return np.clip(pixels, -_MAX_PIXEL, _MAX_PIXEL)

    def _box(
        self,
        x: float,
        y: float,
        heading: float,
        back: float,
        front: float,
        left: float,
        right: float,
    ) -> list[tuple[int, int]]:
        """Pixel corners of a rectangle given in a body frame (back/front along the heading)."""
        local = np.array([[back, right], [front, right], [front, left], [back, left]])
        cos, sin = math.cos(heading), math.sin(heading)
        world = np.stack(
            [x + cos * local[:, 0] - sin * local[:, 1], y + sin * local[:, 0] + cos * local[:, 1]],
            -1,
        )
        return [(round(px), round(py)) for px, py in self._to_pixels(world)]

    def _bar(self, start: np.ndarray, end: np.ndarray, half_width: float) -> list[tuple[int, int]]:
        """Rectangle of half-width ``half_width`` (m) from world point ``start`` to ``end``."""
        delta = end - start
        length = float(np.hypot(*delta))
        heading = math.atan2(delta[1], delta[0])
        return self._box(start[0], start[1], heading, 0.0, length, half_width, -half_width)

    def _polygon(self, corners: list[tuple[int, int]], fill: RGB | None, edge: RGB) -> None:
        gfx = self._pg.gfxdraw
        if fill is not None:
            gfx.filled_polygon(self._surface, corners, fill)
        gfx.aapolygon(self._surface, corners, edge)

    def _disc(self, point: np.ndarray, radius: float, colour: RGB) -> None:
        px, py = (round(v) for v in self._to_pixels(point))
        r = max(2, round(radius * self.pixels_per_metre))
        self._pg.gfxdraw.filled_circle(self._surface, px, py, r, colour)
        self._pg.gfxdraw.aacircle(self._surface, px, py, r, colour)

    def _vehicle(
        self,
        x: float,
        y: float,
        heading: float,
        back: float,
        front: float,
        half_width: float,
        fill: RGB | None,
        edge: RGB,
    ) -> None:
        """A body rectangle with its axle and two wheels at the axle midpoint (x, y)."""
        l = self.params.l
        self._polygon(self._box(x, y, heading, back, front, half_width, -half_width), fill, edge)
        self._polygon(
            self._box(x, y, heading, -0.01 * l, 0.01 * l, half_width, -half_width), edge, edge
        )
        for side in (1.0, -1.0):
            wheel = self._box(
                x,
                y,
                heading,
                -0.13 * l,
                0.13 * l,
                side * (half_width + 0.05 * l),
                side * (half_width - 0.02 * l),
            )
            self._polygon(wheel, None if fill is None else edge, edge)

    # -- drawing --------------------------------------------------------------------------------
    def draw(self, frame: RenderFrame) -> np.ndarray | None:
        """Draw one frame.

        Returns:
            ``(height, width, 3)`` uint8 pixels in "rgb_array" mode; None in "human" mode
            (also once the user has closed the window).

        Raises:
            ValueError: If the frame's arrays do not match ``params.n_trailers``.
        """
        n, p, l = self.params.n_trailers, self.params, self.params.l
        xs, ys, thetas = (np.asarray(v, float) for v in (frame.xs, frame.ys, frame.thetas))
        if not xs.shape == ys.shape == thetas.shape == (n + 1,):
            raise ValueError(f"xs, ys, thetas must have shape ({n + 1},) for n_trailers = {n}")
        if self.render_mode == "human" and self.user_closed:
            return None
        pg, surface = self._pg, self._surface
        self._centre = np.array([xs.mean(), ys.mean()])
        surface.fill(BACKGROUND)
        path = np.asarray(frame.path, dtype=np.float64).reshape(-1, 2)
        if len(path) >= 2:
            pg.draw.aalines(surface, PATH, False, self._to_pixels(path).tolist())
        for marker in frame.markers:
            self._marker(marker)

        colour = margin_colour(frame.singular_margin, self.singular_band)
        axles = np.stack([xs, ys], -1)
        for i in range(1, n + 1):  # rods under the bodies, hitch pins on top of them
            self._polygon(self._bar(axles[i], axles[i - 1], 0.03 * l), colour, INK)
        for i in range(1, n + 1):
            self._vehicle(xs[i], ys[i], thetas[i], -0.25 * l, 0.25 * l, 0.2 * l, colour, INK)
        # The body holds its centre of mass and carries the rail, which may overhang its sides.
        back, front = min(-0.3 * l, p.b - 0.1 * l), max(p.a + 0.3 * l, p.b + 0.1 * l)
        self._vehicle(xs[0], ys[0], thetas[0], back, front, 0.25 * l, colour, INK)
        for i in range(n):
            self._disc(axles[i], 0.04 * l, INK)
        rail = self._box(xs[0], ys[0], thetas[0], p.b - 0.01 * l, p.b + 0.01 * l, p.s_max, -p.s_max)
        self._polygon(rail, RAIL, RAIL)
        for side in (1.0, -1.0):  # end stops at +-s_max
            stop = self._box(
                xs[0],
                ys[0],
                thetas[0],
                p.b - 0.04 * l,
                p.b + 0.04 * l,
                side * p.s_max,
                side * (p.s_max - 0.02 * l),
            )
            self._polygon(stop, RAIL, RAIL)
        xi, eta = frame.mass_xy_body
        cos, sin = math.cos(thetas[0]), math.sin(thetas[0])
        mass = np.array([xs[0] + cos * xi - sin * eta, ys[0] + sin * xi + cos * eta])
        self._disc(mass, 0.08 * l, MASS)

        self._draw_scale_bar()
        if self._font is not None:
            for row, line in enumerate(frame.text.splitlines()):
                image = self._font.render(line, True, INK, BACKGROUND)
                surface.blit(image, (8, 6 + row * self._font.get_linesize()))
        return self._present()

    def _marker(self, marker: Marker) -> None:
        l, colour = self.params.l, marker.colour
        x, y, heading = marker.x, marker.y, marker.heading
        start = np.array([x, y])
        direction = np.array([math.cos(heading), math.sin(heading)])
        if marker.kind == "pose":  # a trailer's outline and its rod
            self._vehicle(x, y, heading, -0.25 * l, 0.25 * l, 0.2 * l, None, colour)
            self._polygon(self._bar(start, start + l * direction, 0.015 * l), None, colour)
            return
        tip = start + 1.6 * l * direction
        self._polygon(self._bar(start, tip - 0.2 * l * direction, 0.03 * l), colour, colour)
        head = self._box(tip[0], tip[1], heading, -0.25 * l, 0.0, 0.12 * l, -0.12 * l)
        self._polygon([head[1], head[3], head[0]], colour, colour)  # tip, back-left, back-right

    def _draw_scale_bar(self) -> None:
        length = round(self.scale_bar_metres * self.pixels_per_metre)
        left, bottom = 12, self.height - 14
        self._pg.draw.rect(self._surface, INK, (left, bottom - 3, length, 3))
        for x in (left, left + length - 2):
            self._pg.draw.rect(self._surface, INK, (x, bottom - 9, 2, 9))
        if self._font is not None:
            label = self._font.render(f"{self.scale_bar_metres:g} m", True, INK, BACKGROUND)
            self._surface.blit(label, (left + length + 6, bottom - label.get_height() + 2))

    def _present(self) -> np.ndarray | None:
        pg = self._pg
        if self.render_mode == "rgb_array":
            pixels = pg.surfarray.pixels3d(self._surface)
            frame = np.array(pixels.transpose(1, 0, 2), dtype=np.uint8, copy=True)
            del pixels  # releases the surface lock
            return frame
        if self._window is None:
            _private_runtime_dir()
            pg.display.init()
            pg.display.set_caption("trailer-env")
            self._window = pg.display.set_mode((self.width, self.height))
            self._clock = pg.time.Clock()
        if any(event.type == pg.QUIT for event in pg.event.get()):
            self.close()
            self.user_closed = True
            return None
        self._window.blit(self._surface, (0, 0))
        pg.display.flip()
        self._clock.tick(self.fps)
        return None

    def close(self) -> None:
        """Close the window, if any (safe to call twice)."""
        if self._window is not None:
            self._pg.display.quit()
            self._window = None


def main(argv: list[str] | None = None) -> None:
    """Write a real frame: Reverse-v0 with three trailers under the LQR baseline, after 5 s."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--out", default="docs/img/render_example.png")
    parser.add_argument("--env", default="trailer_env/Reverse-v0")
    parser.add_argument("--n-trailers", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1003)
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args(argv)
    import gymnasium as gym

    from trailer_env.controllers import LQRController

    # "module:id" makes Gymnasium import trailer_env (which registers the ids) without
    # this module importing its own package.
    env = gym.make(f"trailer_env:{args.env}", n_trailers=args.n_trailers, render_mode="rgb_array")
    controller = LQRController.from_env(env)
    obs, _ = env.reset(seed=args.seed)
    for _ in range(args.steps):
        obs, _, terminated, truncated, _ = env.step(controller(obs))
        if terminated or truncated:
            break
    pixels: Any = env.render()
    assert pixels is not None
    renderer = env.unwrapped._renderer  # type: ignore[attr-defined]
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    renderer._pg.image.save(renderer._surface, args.out)
    env.close()
    print(f"wrote {args.out} ({pixels.shape[1]}x{pixels.shape[0]}): {args.env}, seed {args.seed}")


if __name__ == "__main__":
    main()
