"""The 3D view's initial camera per client: the whole row of stages on any canvas (pure
geometry of ``viewer.row_camera``; the browser test loads the page in a 640 x 420 window)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servodesk.services import viewer as viewer_mod


def row_ends_in_view(n: int, aspect: float, fov: float) -> tuple[float, float]:
    """Where the outer edges of a row of ``n`` discs land across the client's canvas, as
    normalised device x (-1 left edge, +1 right edge), seen from ``row_camera``."""
    look_at, position = viewer_mod.row_camera(n, aspect, fov)
    eye, target = np.array(position), np.array(look_at)
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    half_width = math.tan(fov / 2.0) * aspect
    edges = []
    span = (n - 1) * viewer_mod.SPACING
    for x in (-viewer_mod.DISC_RADIUS, span + viewer_mod.DISC_RADIUS):
        v = np.array((x, 0.0, 0.0)) - eye
        edges.append(float(v @ right) / float(v @ forward) / half_width)
    return edges[0], edges[1]


@pytest.mark.parametrize(("width", "height"), [(380, 420), (520, 260), (300, 700), (1020, 720)])
def test_a_new_clients_camera_shows_the_whole_row_on_its_canvas(width: int, height: int) -> None:
    # viser's default vertical field of view: 75 degrees. The operation page's compact view
    # is about 520 x 260; 380 x 420 is a 640 px window beside the docked panel.
    fov = math.radians(75.0)
    left, right = row_ends_in_view(5, width / height, fov)
    # In view, and not shrunk to a strip in the middle either.
    assert -1.0 < left < -0.4 and 0.4 < right < 1.0, (left, right)


def test_a_wide_canvas_keeps_the_laptop_framing() -> None:
    # Never closer than the initial camera (framed so five labels do not overlap at 1280 px).
    assert viewer_mod.row_camera(5, 1020 / 720, math.radians(75.0)) == viewer_mod.row_camera(5)
    assert viewer_mod.row_camera(5, 3.0, math.radians(75.0)) == viewer_mod.row_camera(5)


@pytest.mark.parametrize(("width", "height"), [(380, 420), (520, 260), (1020, 720)])
def test_the_end_stages_labels_are_whole_on_the_canvas(width: int, height: int) -> None:
    # A label keeps its size on screen (about 100 px): the outer stages' centres stay half a
    # label inside the canvas's edges, or the first and last labels are cut (at 640 px the
    # first axis's name was).
    fov = math.radians(75.0)
    look_at, position = viewer_mod.row_camera(5, width / height, fov, float(width))
    eye, target = np.array(position), np.array(look_at)
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    half_width = math.tan(fov / 2.0) * width / height
    for x in (0.0, 4 * viewer_mod.SPACING):
        v = np.array((x, 0.0, 0.0)) - eye
        px = (float(v @ right) / float(v @ forward) / half_width + 1.0) * width / 2.0
        half = viewer_mod.LABEL_HALF_WIDTH_PX - 1e-6  # At the narrow canvas it is the bound.
        assert half <= px <= width - half, px
