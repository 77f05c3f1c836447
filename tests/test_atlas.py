"""Specification of the atlas algorithm (:mod:`baslip.analysis.atlas`) on manifolds whose
answers are known: a circle, a sphere, a torus and the 3-sphere are covered whole, with
their length, area or volume, and no holes; a domain boundary stops the covering with its
reason, and is recorded even where a neighbour's ball reaching past it closed the way;
separate pieces are found as pieces, and a seed on a covered piece joins it; all pieces
grow together, best-first, so that a chart limit reaches every seed's piece; a chart
limit leaves the atlas marked incomplete; a cap on the system's rank of its points stops
the covering there and changes nothing before it; a ball whose tangent space has turned away does
not close a chart's directions; the chart graph's local minima of a function are one
chart in each of its valleys."""

import math
from dataclasses import replace

import numpy as np
import pytest

from baslip.analysis.atlas import (
    AtlasSettings,
    _Growth,
    ball_pattern,
    ball_volume,
    cover,
    local_minima,
    unit_directions,
)
from baslip.numerics.corrector import Evaluation


class Sphere:
    """|w - centre|^2 = 1 in R^n (a sphere of dimension n - 1), optionally cut at the
    height ``cap`` in its last coordinate."""

    def __init__(self, n: int, centre=None, cap: float | None = None):
        self.n, self.cap = n, cap
        self.centre = np.zeros(n) if centre is None else np.asarray(centre, dtype=float)

    def evaluate(self, w):
        d = w - self.centre
        return Evaluation(np.array([d @ d - 1.0]))

    def jacobian(self, w):
        return 2 * (w - self.centre)[None, :]

    def outside(self, w):
        return "above the cap" if self.cap is not None and w[-1] > self.cap else ""

    def solved(self, w, residual):
        return abs(residual[0]) <= 1e-13


class Torus:
    """(sqrt(x^2 + y^2) - R)^2 + z^2 = r^2 in R^3."""

    R, r = 1.0, 0.4

    def evaluate(self, w):
        q = math.hypot(w[0], w[1])
        return Evaluation(np.array([(q - self.R) ** 2 + w[2] ** 2 - self.r**2]))

    def jacobian(self, w):
        q = math.hypot(w[0], w[1])
        return np.array([[2 * (q - self.R) * w[0] / q, 2 * (q - self.R) * w[1] / q, 2 * w[2]]])

    def outside(self, w):
        return ""

    def solved(self, w, residual):
        return abs(residual[0]) <= 1e-13


def holes(atlas, points) -> int:
    """How many of ``points`` (on the manifold) lie in no chart's ball."""
    centres = np.array([c.center for c in atlas.charts])
    radii = np.array([c.radius for c in atlas.charts])
    distance = np.linalg.norm(points[:, None, :] - centres[None], axis=2)
    return int(np.sum(~np.any(distance < radii[None], axis=1)))


def on_sphere(n: int, count: int, rng) -> np.ndarray:
    points = rng.normal(size=(count, n))
    return points / np.linalg.norm(points, axis=1)[:, None]


SETTINGS = AtlasSettings(radius=0.2, max_radius=0.3, min_radius=0.01)


@pytest.mark.parametrize("n, measure, tolerance", [(2, 2 * math.pi, 0.01), (3, 4 * math.pi, 0.02)])
def test_a_circle_and_a_sphere_are_covered_whole_with_their_measure(n, measure, tolerance):
    seed = np.eye(n)[0]
    atlas = cover(Sphere(n), [seed], n - 1, SETTINGS)
    assert atlas.complete and atlas.piece_count == 1 and atlas.boundaries == ()
    assert abs(sum(atlas.areas) / measure - 1) < tolerance
    assert holes(atlas, on_sphere(n, 3000, np.random.default_rng(0))) == 0
    for chart in atlas.charts:  # every centre solves the equations, and its tangent is orthonormal
        assert abs(np.linalg.norm(chart.center) - 1) < 1e-12
        assert np.allclose(chart.tangent.T @ chart.tangent, np.eye(n - 1), atol=1e-12)
        assert np.allclose(chart.tangent.T @ chart.center, 0, atol=1e-10)


def test_a_torus_is_covered_with_its_area_and_no_holes():
    atlas = cover(Torus(), [np.array([1.4, 0.0, 0.0])], 2, SETTINGS)
    assert atlas.complete and atlas.piece_count == 1
    assert abs(sum(atlas.areas) / (4 * math.pi**2 * Torus.R * Torus.r) - 1) < 0.03
    u, v = np.random.default_rng(1).uniform(0, 2 * np.pi, (2, 3000))
    points = np.column_stack([(1 + 0.4 * np.cos(v)) * np.cos(u), (1 + 0.4 * np.cos(v)) * np.sin(u), 0.4 * np.sin(v)])
    assert holes(atlas, points) == 0


def test_the_local_minima_on_the_chart_graph_are_one_chart_in_each_valley():
    """On the unit circle, cos(3 phi) has three valleys, at phi = pi/3, pi and 5 pi/3: the
    chart graph has exactly one local minimum in each, within a chart's radius of it, and
    a chart whose value is unknown neither counts nor blocks its neighbours."""
    atlas = cover(Sphere(2), [np.eye(2)[0]], 1, SETTINGS)
    phi = [math.atan2(c.center[1], c.center[0]) % (2 * math.pi) for c in atlas.charts]
    values = [math.cos(3 * p) for p in phi]
    minima = local_minima(values, atlas.neighbours)
    assert len(minima) == 3 and [values[i] for i in minima] == sorted(values[i] for i in minima)
    found = sorted(phi[i] for i in minima)
    assert np.allclose(found, [math.pi / 3, math.pi, 5 * math.pi / 3], atol=SETTINGS.max_radius)
    hidden = list(values)
    hidden[minima[0]] = None
    assert minima[0] not in local_minima(hidden, atlas.neighbours)
    assert len(local_minima(hidden, atlas.neighbours)) >= 3


def test_the_three_sphere_is_covered_with_its_volume():
    """(The flat-ball estimate of the measure grows with the charts' radius: 2 % here,
    about 5 % with charts of radius 0.3 to 0.4.)"""
    atlas = cover(Sphere(4), [np.eye(4)[0]], 3, AtlasSettings(radius=0.2, max_radius=0.4, min_radius=0.02))
    assert atlas.complete and atlas.piece_count == 1
    assert abs(sum(atlas.areas) / (2 * math.pi**2) - 1) < 0.03
    assert holes(atlas, on_sphere(4, 3000, np.random.default_rng(2))) == 0


def test_a_domain_boundary_stops_the_covering_and_says_why():
    atlas = cover(Sphere(3, cap=0.5), [np.array([1.0, 0.0, 0.0])], 2, SETTINGS)
    assert atlas.complete and atlas.boundaries
    assert {b.reason for b in atlas.boundaries} == {"above the cap"} and {b.kind for b in atlas.boundaries} == {"domain"}
    assert all(b.point[-1] > 0.5 for b in atlas.boundaries)  # each aimed past the cap
    # The area below the cap at height 0.5 is 2 pi (1 + 0.5); balls reaching past the cap add nothing.
    assert abs(sum(atlas.areas) / (2 * math.pi * 1.5) - 1) < 0.03
    points = on_sphere(3, 4000, np.random.default_rng(3))
    assert holes(atlas, points[points[:, 2] < 0.45]) == 0


def edge_without_record(atlas, edge: np.ndarray) -> int:
    """How many points of the domain's ``edge`` (on the manifold) lie in the ball of no
    chart that has a boundary recorded."""
    recorded = sorted({b.chart for b in atlas.boundaries})
    if not recorded:
        return len(edge)
    centres = np.array([atlas.charts[i].center for i in recorded])
    radii = np.array([atlas.charts[i].radius for i in recorded])
    distance = np.linalg.norm(edge[:, None, :] - centres[None], axis=2)
    return int(np.sum(~np.any(distance < radii[None], axis=1)))


def test_an_edge_hidden_in_a_neighbours_ball_is_still_recorded():
    """Large balls reach past the cap, so a neighbour closes a chart's direction that
    points past it without a step being tried there; the edge is recorded all the same:
    both ends of the capped circle, and every point of the capped sphere's rim, lie in
    the ball of a chart with a boundary row."""
    settings = AtlasSettings(radius=0.2, max_radius=1.0, min_radius=0.01)
    arc = cover(Sphere(2, cap=0.5), [np.array([0.0, -1.0])], 1, settings)
    ends = np.array([[math.sqrt(0.75), 0.5], [-math.sqrt(0.75), 0.5]])
    assert edge_without_record(arc, ends) == 0
    assert {b.reason for b in arc.boundaries} == {"above the cap"} and {b.kind for b in arc.boundaries} == {"domain"}
    cap = cover(Sphere(3, cap=0.5), [np.array([1.0, 0.0, 0.0])], 2, settings)
    turn = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    rim = np.column_stack([math.sqrt(0.75) * np.cos(turn), math.sqrt(0.75) * np.sin(turn), np.full(400, 0.5)])
    assert edge_without_record(cap, rim) == 0
    assert cap.complete and all(b.point[-1] > 0.5 for b in cap.boundaries)


def test_separate_pieces_are_found_and_a_seed_on_a_covered_piece_joins_it():
    """Two unit circles 3 apart (one system): four seeds, three on the first circle, of
    which one lies in the first seed's ball. The two charts seeded apart on the first
    circle grow into each other and merge into one piece."""

    class TwoCircles(Sphere):
        def evaluate(self, w):
            a, b = w @ w - 1.0, (w - [3.0, 0.0]) @ (w - [3.0, 0.0]) - 1.0
            return Evaluation(np.array([a * b]))

        def jacobian(self, w):
            a, b = w @ w - 1.0, (w - [3.0, 0.0]) @ (w - [3.0, 0.0]) - 1.0
            return (2 * w * b + 2 * (w - [3.0, 0.0]) * a)[None, :]

    seeds = [np.array([1.0, 0.0]), np.array([0.0, -1.0]), np.array([4.0, 0.0]),
             np.array([math.cos(0.1), math.sin(0.1)]), None]
    atlas = cover(TwoCircles(2), seeds, 1, SETTINGS)
    assert [s.outcome for s in atlas.seeds] == ["new piece", "new piece", "new piece", "on a covered piece", "failed"]
    assert atlas.seeds[3].chart == atlas.seeds[0].chart
    assert atlas.piece_count == 2
    assert atlas.pieces[atlas.seeds[0].chart] == atlas.pieces[atlas.seeds[1].chart] != atlas.pieces[atlas.seeds[2].chart]
    for piece in (0, 1):
        assert abs(atlas.piece_area(piece) / (2 * math.pi) - 1) < 0.01


def test_all_pieces_grow_together_best_first_so_a_chart_limit_reaches_every_seed():
    """Two circles, a limit of 12 charts and a priority (-x) that ranks every point of the
    second circle before any of the first: the first seed's circle keeps its one chart,
    and the other 11 grow on the second (one piece after the other, all 12 would have
    gone to the first circle, which takes 32)."""

    class RankedCircles(Sphere):
        def evaluate(self, w):
            a, b = w @ w - 1.0, (w - [3.0, 0.0]) @ (w - [3.0, 0.0]) - 1.0
            return Evaluation(np.array([a * b]))

        def jacobian(self, w):
            a, b = w @ w - 1.0, (w - [3.0, 0.0]) @ (w - [3.0, 0.0]) - 1.0
            return (2 * w * b + 2 * (w - [3.0, 0.0]) * a)[None, :]

        def priority(self, w):
            return -float(w[0])  # the right-hand side of the right-hand circle first

    seeds = [np.array([-1.0, 0.0]), np.array([2.0, 0.0])]
    atlas = cover(RankedCircles(2), seeds, 1, AtlasSettings(radius=0.2, max_radius=0.2, max_charts=12))
    assert len(atlas.charts) == 12 and not atlas.complete
    assert [c.index for c in atlas.charts if c.center[0] < 1.5] == [atlas.seeds[0].chart]
    assert atlas.piece_count == 2


def test_a_chart_limit_leaves_the_atlas_incomplete_and_says_so():
    atlas = cover(Sphere(3), [np.array([1.0, 0.0, 0.0])], 2, AtlasSettings(radius=0.2, max_radius=0.3, max_charts=40))
    assert not atlas.complete and len(atlas.charts) == 40
    assert "chart limit reached" in {b.reason for b in atlas.boundaries}
    assert "limit" in {b.kind for b in atlas.boundaries}


def test_where_the_corrector_gives_up_the_atlas_is_not_complete():
    """A region where Newton can never meet the tolerance is not an edge of the manifold:
    it is recorded as a corrector stop, and the atlas does not call itself complete."""

    class Stubborn(Sphere):
        def solved(self, w, residual):
            return w[2] <= 0.8 and abs(residual[0]) <= 1e-13

    atlas = cover(Stubborn(3), [np.array([1.0, 0.0, 0.0])], 2, SETTINGS)
    kinds = {b.kind for b in atlas.boundaries}
    assert kinds == {"corrector"} and not atlas.complete
    assert all(b.reason.startswith("Newton") for b in atlas.boundaries)


class RankedSphere(Sphere):
    """A sphere ranked by its height: the atlas grows from its lowest charts first."""

    def priority(self, w):
        return float(w[-1])


def test_a_cap_on_the_rank_stops_the_covering_there_and_changes_nothing_before_it():
    """A sphere ranked by height, capped at 0.5: the part below the cap is covered whole
    (no holes), no chart above the cap is grown from, each of its open directions is a
    ``cap`` edge, and the atlas is complete up to the cap. The charts are the first ones
    of the same covering without the cap, in the same order."""
    capped = cover(RankedSphere(3), [np.array([1.0, 0.0, 0.0])], 2, replace(SETTINGS, max_priority=0.5))
    rank = [c.center[-1] for c in capped.charts]
    assert capped.complete and {b.kind for b in capped.boundaries} == {"cap"}
    assert all(rank[c.parent] <= 0.5 for c in capped.charts if c.parent is not None)
    assert {b.chart for b in capped.boundaries} <= {i for i, r in enumerate(rank) if r > 0.5}
    assert all(b.reason.endswith("above the cap 0.5") for b in capped.boundaries)
    points = on_sphere(3, 4000, np.random.default_rng(5))
    assert holes(capped, points[points[:, 2] < 0.5]) == 0
    assert holes(capped, points[points[:, 2] > 0.9]) > 0  # the cap left the top uncovered
    whole = cover(RankedSphere(3), [np.array([1.0, 0.0, 0.0])], 2, SETTINGS)
    assert len(whole.charts) > len(capped.charts)
    assert all(np.array_equal(a.center, b.center) for a, b in zip(capped.charts, whole.charts))


@pytest.mark.parametrize("k", [1, 2, 3])
def test_directions_are_unit_and_the_ball_pattern_fills_the_unit_ball(k):
    directions = unit_directions(k)
    assert np.allclose(np.linalg.norm(directions, axis=1), 1.0)
    assert abs(directions.mean(axis=0)).max() < 0.01  # spread evenly: they balance
    pattern = ball_pattern(k)
    assert np.linalg.norm(pattern, axis=1).max() <= 1.0
    assert abs(np.mean(np.linalg.norm(pattern, axis=1) ** 2) - k / (k + 2)) < 0.02  # uniform in the ball
    assert ball_volume(2, 1.0) == pytest.approx(math.pi) and ball_volume(3, 2.0) == pytest.approx(32 * math.pi / 3)


def test_a_ball_whose_tangent_has_turned_away_does_not_close_a_charts_directions():
    """On the unit sphere, a chart at (1, 0, 0) and a large one 60 deg away along the
    equator whose ball holds some of the first chart's boundary points: those stay open,
    since the second chart's tangent plane has turned by 60 deg (more than max_turn); a
    chart 20 deg away, as large, closes them."""
    sphere, settings = Sphere(3), AtlasSettings(radius=0.3, max_radius=1.5)

    def chart_at(angle, radius, growth):
        centre = np.array([math.cos(angle), math.sin(angle), 0.0])
        tangent = np.column_stack([[-math.sin(angle), math.cos(angle), 0.0], [0.0, 0.0, 1.0]])
        return growth.add(centre, tangent, sphere.jacobian(centre), radius, None, 0, 0)

    for angle, closes in ((math.radians(60), False), (math.radians(20), True)):
        growth = _Growth(sphere, settings, 2)
        growth.parent_piece.append(0)
        first = chart_at(0.0, 0.3, growth)
        far = chart_at(angle, 1.0, growth)
        inside = [d for d in range(len(growth.directions))
                  if np.linalg.norm(growth.boundary_point(first, d) - far.center) < far.radius]
        assert inside  # the large ball holds some of the first chart's boundary points
        assert all(not growth.open[first.index][d] for d in inside) == closes
