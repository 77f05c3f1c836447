"""An atlas of a k-dimensional solution manifold F(w) = 0: charts that cover it, piece by piece.

This is Henderson's multiple-parameter continuation in the form Dankowicz and Schilder
describe for COCO's ``atlas_kd``, simplified where baslip's dimensions (k = 1 to 3) allow:

* A **chart** is a point w0 with F(w0) = 0, an orthonormal basis T of the null space of
  dF/dw there (the tangent space, from the SVD of the Jacobian) and a radius R. Its ball
  is the set of points within R of w0.
* A chart's **boundary** is kept as a fixed set of unit directions d in its tangent
  space (2 for k = 1, :data:`DIRECTIONS_2D` for k = 2, :data:`DIRECTIONS_3D` for k = 3),
  each standing for the boundary point w0 + R T d. Henderson keeps an exact polyhedron
  per chart instead; with directions this dense and neighbours at most R apart, the
  balls overlap so much that the sampled boundary leaves no holes on the test manifolds
  (the tests check it on a sphere, a torus and the 3-sphere).
* A direction is **covered** when its boundary point lies inside the ball of a
  neighbour (a chart whose ball overlaps this one's) whose tangent space is within
  :data:`COVER_TURN` times :attr:`AtlasSettings.max_turn` of this one's: where two sheets
  of the manifold pass close in the ambient space, their balls overlap too.
  The atlas grows from the charts with uncovered directions, oldest first (or, if the
  system ranks its points, most interesting first): a new centre
  is predicted at w0 + h T d (h = R) and corrected by Newton's method on
  [F(w) = 0, T^T (w - w_pred) = 0], a square system (:mod:`baslip.numerics.corrector`:
  the chart's own Jacobian, updated by Broyden's formula, refreshed where convergence is
  slow, and a fresh Jacobian's step halved until the residual falls). Where Newton
  fails, the step turns the tangent by more than :attr:`AtlasSettings.max_turn` or lands
  outside the domain, h is halved, down to the least radius.
* The covering **stops** where no step is left: every direction covered, or recorded as
  a boundary with its reason and its kind (:data:`EDGE_KINDS`): the domain's edge (a
  bound, or an evaluation that fails, such as a fall), a singular chart (the equations
  lose rank, or the projection onto the tangent space folds), the corrector (Newton
  diverging or not converging, the tangent turning too fast at the least step) or the
  chart limit. Only the first two are edges of the manifold: an atlas with a boundary of
  the other two kinds is not complete, and says so. A system that ranks its points may
  also have the covering stop where its rank passes a cap
  (:attr:`AtlasSettings.max_priority`): charts ranked above it are made but not grown
  from, and their open directions are recorded as boundaries of kind ``cap``. An atlas
  whose other boundaries are edges is then complete up to the cap: it holds every point
  that the seeds' pieces reach through charts ranked within it. A direction that a
  neighbour's ball closed, but whose boundary point lies outside the domain, is recorded
  as an edge of the domain too: a ball reaching past the edge would otherwise hide that
  edge from the table.
* **Pieces.** All seeds are projected first: a seed that lies in an earlier seed's ball
  belongs to that chart's piece; any other starts a new piece. Then all pieces grow
  together from one best-first queue (so that the most interesting parts near every
  seed are covered before a chart limit, not only the first seed's piece), and pieces
  whose charts come to overlap are merged.
* **Area.** Each chart's share of the manifold's k-volume is estimated by a partition of
  unity: its ball's volume times the mean, over a fixed pattern of points in the ball,
  of 1 / (the number of balls holding the point). The shares add up to the covered
  volume (tested against a sphere's area).

Distances are taken in the coordinates w that the system chooses; the system scales its
quantities so that a unit means the same everywhere.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from baslip.numerics.corrector import SINGULAR_RANK, ManifoldSystem, correct, kind_of, project_seed

#: Boundary directions of a chart of a 2-dimensional manifold (every 30 deg).
DIRECTIONS_2D = 12
#: ... of a 3-dimensional manifold (a Fibonacci lattice on the sphere).
DIRECTIONS_3D = 32
#: Points of the fixed pattern in a chart's ball for its area share.
AREA_SAMPLES = {1: 32, 2: 96, 3: 192}
#: A neighbour covers a chart's boundary point only if their tangent spaces are within
#: this many times :attr:`AtlasSettings.max_turn`, the bound a chart and the chart it grew
#: from meet. At twice that, an upright cell of the gait atlas still closed itself falsely
#: around a strip of theta_h between 89 and 91 deg (charts of radius 1.5 to 3 whose
#: tangents differed by 30 to 60 deg).
COVER_TURN = 1.0
#: Charts between two progress reports.
PROGRESS_CHARTS = 100
#: Corrector iterations (updated-Jacobian steps included) of a step that counts as easy, so that the
#: next chart may be larger.
EASY_ITERATIONS = 8


@dataclass(frozen=True)
class AtlasSettings:
    """How the atlas grows.

    Parameters
    ----------
    radius : float
        Radius of a piece's first chart, in the system's coordinates.
    min_radius, max_radius : float
        The least radius a step may shrink to before a boundary is recorded, and the
        largest a chart may grow to.
    max_charts : int
        Charts at most; directions still open when it is reached are recorded as
        boundaries with the reason "chart limit reached".
    newton_iterations : int
        Corrector iterations at most.
    max_turn : float
        Largest angle [rad] between the tangent spaces of a chart and the chart it grew
        from; a step that turns more is halved.
    grow : float
        Factor by which the radius grows after an easy step (the corrector done in
        :data:`EASY_ITERATIONS` iterations, the tangent turned by less than a quarter of
        ``max_turn``).
    max_priority : float
        Charts whose priority (see :func:`cover`) exceeds it are not grown from: their
        open directions are recorded as boundaries of kind ``cap``. Infinite (no cap) by
        default; it needs a system that ranks its points.
    """

    radius: float = 0.2
    min_radius: float = 0.01
    max_radius: float = 1.0
    max_charts: int = 2000
    newton_iterations: int = 20
    max_turn: float = math.radians(30)
    grow: float = 1.3
    max_priority: float = math.inf


@dataclass(frozen=True)
class Chart:
    """One chart: centre ``center``, tangent basis ``tangent`` (columns, orthonormal),
    ``radius``; ``parent`` is the chart it grew from (None for a piece's first), and
    ``iterations`` the corrector iterations it took."""

    index: int
    center: np.ndarray
    tangent: np.ndarray
    radius: float
    jacobian: np.ndarray
    parent: int | None
    iterations: int


#: Kinds of boundary: where the manifold ends (``domain``, ``singular``), where the
#: covering gave up without knowing (``corrector``, ``limit``), and where the system's rank
#: of its points passed the cap (``cap``: the manifold goes on, ranked worse).
EDGE_KINDS = ("domain", "singular", "corrector", "limit", "cap")


@dataclass(frozen=True)
class Boundary:
    """Where the covering stopped: the direction ``direction`` (tangent coordinates) of
    chart ``chart``, the point it aimed at, why, and the kind of edge (:data:`EDGE_KINDS`)."""

    chart: int
    direction: np.ndarray
    point: np.ndarray
    reason: str
    kind: str = "domain"


@dataclass(frozen=True)
class SeedOutcome:
    """What became of a seed: the chart or piece it gave (None if it failed) and how."""

    seed: int
    outcome: str  # "new piece", "on a covered piece", "failed", "not taken" (the chart limit was reached)
    chart: int | None
    note: str = ""


@dataclass(frozen=True)
class Atlas:
    """A finished covering."""

    charts: tuple[Chart, ...]
    neighbours: tuple[tuple[int, ...], ...]
    pieces: tuple[int, ...]  # piece of each chart, numbered 0, 1, ... by first chart
    areas: tuple[float, ...]  # each chart's share of the covered k-volume
    boundaries: tuple[Boundary, ...]
    seeds: tuple[SeedOutcome, ...]
    dimension: int
    complete: bool  # False if the chart limit or the corrector stopped the covering somewhere

    @property
    def piece_count(self) -> int:
        return len(set(self.pieces))

    def piece_area(self, piece: int, where: Callable[[int], bool] | None = None) -> float:
        """Covered k-volume of ``piece``, or of its charts for which ``where(index)``."""
        return float(sum(a for i, (p, a) in enumerate(zip(self.pieces, self.areas))
                         if p == piece and (where is None or where(i))))


def unit_directions(k: int) -> np.ndarray:
    """The boundary directions of a chart of a k-dimensional manifold (rows, unit)."""
    if k == 1:
        return np.array([[1.0], [-1.0]])
    if k == 2:
        angles = 2 * np.pi * np.arange(DIRECTIONS_2D) / DIRECTIONS_2D
        return np.column_stack([np.cos(angles), np.sin(angles)])
    if k == 3:
        return _fibonacci_sphere(DIRECTIONS_3D)
    raise ValueError(f"the atlas covers manifolds of dimension 1 to 3, not {k}")


def _fibonacci_sphere(count: int) -> np.ndarray:
    i = np.arange(count) + 0.5
    polar = np.arccos(1 - 2 * i / count)
    azimuth = np.pi * (1 + 5**0.5) * i
    return np.column_stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)])


def ball_pattern(k: int) -> np.ndarray:
    """A fixed, evenly spread set of points in the unit k-ball (rows)."""
    count = AREA_SAMPLES[k]
    i = np.arange(count) + 0.5
    if k == 1:
        return (2 * i / count - 1)[:, None]
    if k == 2:  # a sunflower: equal area per point
        angle = np.pi * (3 - 5**0.5) * i
        return np.column_stack([np.cos(angle), np.sin(angle)]) * np.sqrt(i / count)[:, None]
    return _fibonacci_sphere(count) * np.cbrt(i / count)[:, None]


def ball_volume(k: int, radius: float) -> float:
    """Volume of a k-ball of ``radius``."""
    return math.pi ** (k / 2) / math.gamma(k / 2 + 1) * radius**k


def tangent_basis(jacobian: np.ndarray, k: int) -> np.ndarray | None:
    """An orthonormal basis (columns) of the null space of ``jacobian``, whose rank must
    be its row count; None if it is less (a singular point)."""
    _, s, vt = np.linalg.svd(jacobian)
    rows = jacobian.shape[0]
    if s.size < rows or s[rows - 1] <= 1e-10 * max(s[0], 1e-300):
        return None
    return vt[rows : rows + k].T


def oriented(tangent: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``tangent`` rotated within its span to lie as close as possible to ``reference``
    (orthogonal Procrustes), so that neighbouring charts' directions line up."""
    u, _, vt = np.linalg.svd(tangent.T @ reference)
    return tangent @ (u @ vt)


def turn_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Largest principal angle [rad] between the spans of the orthonormal bases a and b."""
    s = np.linalg.svd(a.T @ b, compute_uv=False)
    return float(np.arccos(np.clip(s.min(), -1.0, 1.0)))


class _Growth:
    """The atlas while it grows: the one mutable object here, private to :func:`cover`."""

    def __init__(self, system: ManifoldSystem, settings: AtlasSettings, k: int,
                 progress: Callable[[int, int], None] | None = None, on_chart: Callable[[Chart], None] | None = None):
        self.system, self.settings, self.k, self.progress, self.on_chart = system, settings, k, progress, on_chart
        self.directions = unit_directions(k)
        self.charts: list[Chart] = []
        self.centers: list[np.ndarray] = []
        self.open: list[np.ndarray] = []  # per chart: which directions are still open
        self.neighbours: list[set[int]] = []
        self.alignment: dict[tuple[int, int], bool] = {}  # (chart, neighbour): see aligned
        self.parent_piece: list[int] = []  # union-find over pieces
        self.piece_of: list[int] = []
        self.boundaries: list[Boundary] = []
        self.closed_by_neighbour: list[tuple[int, int]] = []  # (chart, direction), in the order closed
        self.seeds_taken = 0  # all of them by the time the pieces grow (see cover)

    # -- pieces ----------------------------------------------------------------------------

    def root(self, piece: int) -> int:
        while self.parent_piece[piece] != piece:
            self.parent_piece[piece] = self.parent_piece[self.parent_piece[piece]]
            piece = self.parent_piece[piece]
        return piece

    def merge(self, a: int, b: int) -> None:
        a, b = self.root(a), self.root(b)
        if a != b:
            self.parent_piece[max(a, b)] = min(a, b)

    # -- covering --------------------------------------------------------------------------

    def covering_chart(self, point: np.ndarray, skip: int | None = None) -> int | None:
        """A chart whose ball holds ``point`` (the first), or None."""
        if not self.centers:
            return None
        distance = np.linalg.norm(np.asarray(self.centers) - point, axis=1)
        radii = np.array([c.radius for c in self.charts])
        if skip is not None:
            distance[skip] = np.inf
        inside = np.nonzero(distance < radii)[0]
        return int(inside[0]) if inside.size else None

    def boundary_point(self, chart: Chart, d) -> np.ndarray:
        return chart.center + chart.radius * chart.tangent @ self.directions[d]

    def add(self, center: np.ndarray, tangent: np.ndarray, jacobian: np.ndarray, radius: float,
            parent: int | None, iterations: int, piece: int) -> Chart:
        chart = Chart(len(self.charts), center, tangent, radius, jacobian, parent, iterations)
        self.charts.append(chart)
        self.centers.append(center)
        self.open.append(np.ones(len(self.directions), dtype=bool))
        self.piece_of.append(piece)
        distance = np.linalg.norm(np.asarray(self.centers[:-1]) - center, axis=1) if chart.index else np.zeros(0)
        radii = np.array([c.radius for c in self.charts[:-1]])
        near = {int(j) for j in np.nonzero(distance < radii + radius)[0]}
        self.neighbours.append(near)
        for j in near:
            self.neighbours[j].add(chart.index)
            self.merge(self.piece_of[j], piece)
        for j in (chart.index, *near):
            self.close_covered(j)
        if self.on_chart is not None:
            self.on_chart(chart)
        return chart

    def close_covered(self, j: int) -> None:
        """Close the open directions of chart ``j`` whose boundary points its neighbours
        cover: neighbours whose tangent spaces are within :data:`COVER_TURN` times
        ``max_turn`` of its own. Where two sheets of the manifold pass close in the ambient
        space, their balls overlap too, and would otherwise close each other's directions."""
        chart = self.charts[j]
        aligned = [n for n in self.neighbours[j] if self.aligned(j, n)]
        open_directions = np.nonzero(self.open[j])[0]
        if not aligned or not open_directions.size:
            return
        points = np.array([self.boundary_point(chart, d) for d in open_directions])
        centers = np.array([self.centers[n] for n in aligned])
        radii = np.array([self.charts[n].radius for n in aligned])
        gaps = np.sqrt(np.sum((points[:, None, :] - centers[None, :, :]) ** 2, axis=2))
        for d in open_directions[(gaps < radii).any(axis=1)]:
            self.open[j][d] = False
            self.closed_by_neighbour.append((j, int(d)))

    def aligned(self, j: int, n: int) -> bool:
        """Whether neighbour ``n``'s tangent space is within :data:`COVER_TURN` times
        ``max_turn`` of chart ``j``'s: computed once a pair, since every chart added
        closes the directions of all its neighbours again."""
        if (j, n) not in self.alignment:
            turn = turn_angle(self.charts[j].tangent, self.charts[n].tangent)
            self.alignment[j, n] = turn <= COVER_TURN * self.settings.max_turn
        return self.alignment[j, n]

    def grow(self, firsts: Sequence[int]) -> None:
        """Grow the pieces of the charts ``firsts`` together until no direction is open (or
        the limit): from the chart of least priority of them all first, if the system
        ranks its points (see :func:`cover`), else oldest first."""
        rank = getattr(self.system, "priority", None)
        queue = [(rank(self.centers[c]) if rank else float(c), c) for c in firsts]
        heapq.heapify(queue)
        while queue:
            priority, c = heapq.heappop(queue)
            if rank and priority > self.settings.max_priority:
                self.close_at_cap(c, priority)
                continue
            for d in range(len(self.directions)):
                if not self.open[c][d]:
                    continue
                if len(self.charts) >= self.settings.max_charts:
                    return
                made = self.step(self.charts[c], d)
                self.open[c][d] = False
                if made is not None:
                    heapq.heappush(queue, (rank(made.center) if rank else float(made.index), made.index))
                    if self.progress is not None and len(self.charts) % PROGRESS_CHARTS == 0:
                        self.progress(len(self.charts), self.seeds_taken)

    def step(self, chart: Chart, d: int) -> Chart | None:
        """One step from ``chart`` along its direction ``d``: the new chart, or None with
        a boundary recorded."""
        s = self.settings
        h, reason, kind, target = chart.radius, "", "domain", chart.center
        direction = chart.tangent @ self.directions[d]
        while h >= s.min_radius * (1 - 1e-12):
            target = chart.center + h * direction
            reason, kind = self.system.outside(target), "domain"
            if not reason:
                found = correct(self.system, target, chart.tangent, chart.jacobian, s.newton_iterations)
                if isinstance(found, str):
                    reason, kind = found, kind_of(found)
                else:
                    w, jacobian, iterations = found
                    reason = self.system.outside(w)
                    tangent = tangent_basis(jacobian, self.k)
                    if tangent is None:
                        reason, kind = SINGULAR_RANK, "singular"
                    elif not reason:
                        tangent = oriented(tangent, chart.tangent)
                        turn = turn_angle(tangent, chart.tangent)
                        if turn <= s.max_turn:
                            easy = iterations <= EASY_ITERATIONS and turn <= s.max_turn / 4
                            radius = min(s.max_radius, h * s.grow) if easy else h
                            return self.add(w, tangent, jacobian, radius, chart.index, iterations,
                                            self.piece_of[chart.index])
                        reason = f"the tangent turns by {math.degrees(turn):.0f} deg within the least step"
                        kind = "corrector"
            h /= 2
        self.boundaries.append(Boundary(chart.index, self.directions[d].copy(), target, reason, kind))
        return None

    def record_edges_past_neighbours(self) -> None:
        """Record, as edges of the domain, the directions that a neighbour's ball closed
        although their boundary points lie outside the domain: there the manifold leaves
        the domain within the chart's radius, and no step was taken that would have said
        so (a ball reaching past the edge would otherwise hide it from the table). A chart
        that has an edge recorded already, by a step or by an earlier such direction (in
        the order they were closed), gets no second row: one row per chart the edge
        passes through is enough to place it, and keeps the table the size of the edge."""
        if not self.closed_by_neighbour:
            return
        points = np.array([self.boundary_point(self.charts[j], d) for j, d in self.closed_by_neighbour])
        inside = np.asarray(domain_test(self.system)(points), dtype=bool)
        recorded = {b.chart for b in self.boundaries if b.kind == "domain"}
        for (j, d), point, held in zip(self.closed_by_neighbour, points, inside):
            if held or j in recorded:
                continue
            reason = self.system.outside(point) or "outside the domain"
            self.boundaries.append(Boundary(j, self.directions[d].copy(), point, reason, "domain"))
            recorded.add(j)

    def close_at_cap(self, c: int, priority: float) -> None:
        """Record the open directions of chart ``c``, ranked ``priority`` above the cap, as
        boundaries of kind ``cap``: the covering does not grow from it."""
        chart, still = self.charts[c], self.open[c]
        reason = f"ranked {priority:.4g}, above the cap {self.settings.max_priority:g}"
        for d in np.nonzero(still)[0]:
            self.boundaries.append(Boundary(c, self.directions[d].copy(), self.boundary_point(chart, d), reason, "cap"))
        still[:] = False

    def close_at_limit(self) -> bool:
        """Record every still-open direction as stopped by the chart limit; whether any was."""
        stopped = False
        for chart, still in zip(self.charts, self.open):
            for d in np.nonzero(still)[0]:
                self.boundaries.append(Boundary(chart.index, self.directions[d].copy(),
                                                self.boundary_point(chart, d), "chart limit reached", "limit"))
                stopped = True
            still[:] = False
        return stopped


def cover(system: ManifoldSystem, seeds: Iterable[np.ndarray | None], k: int,
          settings: AtlasSettings = AtlasSettings(), progress: Callable[[int, int], None] | None = None,
          on_chart: Callable[[Chart], None] | None = None) -> Atlas:
    """Cover the solution set of ``system`` (of dimension ``k``) from ``seeds``.

    Parameters
    ----------
    system : ManifoldSystem
        The equations and their domain. If it has a method ``priority(w)``, each piece
        grows from its chart of least priority first (best-first), so that a chart limit
        leaves the most interesting part covered; else oldest first (breadth-first).
    seeds : iterable of arrays or None
        Starting points; each is projected onto F = 0 first. A seed that lies in an
        earlier seed's ball joins that chart's piece; any other starts a new piece. Then
        all pieces grow together, best-first over all of them, so that a chart limit is
        not spent on the first seed's piece alone; pieces whose charts come to overlap
        merge. None stands for a seed that could not be made (its failure is counted).
    k : int
        Dimension of the manifold, 1 to 3.
    settings : AtlasSettings
        Radii, limits and tolerances.
    progress : callable, optional
        Called as ``progress(charts, seeds taken)`` every :data:`PROGRESS_CHARTS` charts
        and at the end.
    on_chart : callable, optional
        Called with each chart as it is made (in the order of ``Atlas.charts``), so that
        the caller can start on its report while the covering goes on.

    Returns
    -------
    Atlas
    """
    growth = _Growth(system, settings, k, progress=progress, on_chart=on_chart)
    outcomes = [_take_seed(growth, number, seed) for number, seed in enumerate(seeds)]
    growth.seeds_taken = len(outcomes)
    growth.grow([o.chart for o in outcomes if o.outcome == "new piece" and o.chart is not None])
    if progress is not None:
        progress(len(growth.charts), growth.seeds_taken)
    growth.record_edges_past_neighbours()
    growth.close_at_limit()
    complete = not any(b.kind in ("corrector", "limit") for b in growth.boundaries)
    roots = [growth.root(p) for p in growth.piece_of]
    numbering = {root: n for n, root in enumerate(dict.fromkeys(roots))}
    return Atlas(
        charts=tuple(growth.charts),
        neighbours=tuple(tuple(sorted(n)) for n in growth.neighbours),
        pieces=tuple(numbering[r] for r in roots),
        areas=tuple(chart_areas(growth.charts, growth.neighbours, k, domain_test(system))),
        boundaries=tuple(growth.boundaries),
        seeds=tuple(outcomes),
        dimension=k,
        complete=complete,
    )


def domain_test(system: ManifoldSystem) -> Callable[[np.ndarray], np.ndarray]:
    """The system's test of many points (rows) for lying in its domain: its own
    ``inside(points)`` if it has one, else :meth:`ManifoldSystem.outside` point by point."""
    many = getattr(system, "inside", None)
    if many is not None:
        return many
    return lambda points: np.array([not system.outside(q) for q in points], dtype=bool)


def _take_seed(growth: _Growth, number: int, seed: np.ndarray | None) -> SeedOutcome:
    if seed is None:
        return SeedOutcome(number, "failed", None, "no starting solution")
    projected = project_seed(growth.system, seed)
    if isinstance(projected, str):
        return SeedOutcome(number, "failed", None, projected)
    w, jacobian = projected
    covering = growth.covering_chart(w)
    if covering is not None:
        return SeedOutcome(number, "on a covered piece", covering)
    if len(growth.charts) >= growth.settings.max_charts:
        return SeedOutcome(number, "not taken", None, "chart limit reached")
    reason = growth.system.outside(w)
    tangent = tangent_basis(jacobian, growth.k)
    if reason or tangent is None:
        return SeedOutcome(number, "failed", None, reason or "singular point")
    piece = len(growth.parent_piece)
    growth.parent_piece.append(piece)
    chart = growth.add(w, tangent, jacobian, growth.settings.radius, None, 0, piece)
    return SeedOutcome(number, "new piece", chart.index)


def chart_areas(charts: Sequence[Chart], neighbours: Sequence[set[int]], k: int,
                inside: Callable[[np.ndarray], np.ndarray] | None = None) -> list[float]:
    """Each chart's share of the covered k-volume, by a partition of unity over a fixed
    pattern of points in its ball (see the module docstring); points not ``inside`` the
    domain (a test of many points, rows, at once) count for nothing, so that balls
    reaching past a boundary add no area."""
    pattern = ball_pattern(k)
    areas = []
    for chart in charts:
        points = chart.center + chart.radius * pattern @ chart.tangent.T
        count = np.ones(len(points))
        for n in neighbours[chart.index]:
            # Measured in the neighbour's tangent coordinates: a point of this chart's
            # tangent plane lies off the manifold by about R^2 / 2, which a plain distance
            # would count against it (and so overstate the area by a few per cent).
            offset = points - charts[n].center
            count += np.linalg.norm(offset @ charts[n].tangent, axis=1) < charts[n].radius
        held = np.ones(len(points)) if inside is None else np.asarray(inside(points), dtype=float)
        areas.append(ball_volume(k, chart.radius) * float(np.mean(held / count)))
    return areas


def local_minima(values: Sequence[float | None], neighbours: Sequence[Sequence[int]]) -> list[int]:
    """The charts where ``values`` is least among their neighbours on the chart graph, in
    increasing order of value: one chart in each valley of the value over the manifold
    (ties count each chart). A chart whose value is None (not known) is neither a minimum
    nor compared against."""
    known = {i: value for i, value in enumerate(values) if value is not None}
    minima = [i for i, value in known.items() if all(known.get(n, value) >= value for n in neighbours[i])]
    return sorted(minima, key=known.__getitem__)
