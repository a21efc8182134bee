"""Grid Markov localization with the entropy and novelty filters (Fox, Burgard, Thrun & Cremers 1998).

The belief ``Bel(l)`` over poses ``l = <x, y, theta>`` lives on a position probability grid: 15 cm
cells times 2 degree heading layers ("in all our experiments, the resolution of robot orientation
was 2 deg, and the spatial resolution was 15cm", Sec. "Markov localization"), on the free cells of
the map. Each update is::

    motion  (Eq. 1)  Bel(l) <- sum_l' p(l | l', a) Bel(l')      convolution with the odometry model
    mixture          Bel(l) <- (1 - eps) Bel(l) + eps / |L|      a small uniform part, for recovery
    filter  (Eq. 3-6) which beams s_b of the scan are believable  entropy or novelty filter
    sensor  (Eq. 2)  Bel(l) <- alpha (prod_{b used} p(s_b | l))^k Bel(l)   k = likelihood_power

Only poses with non-negligible belief are held (the selective update that makes the grid fast):
after each step the poses below ``prune_ratio`` times the largest belief are dropped. The uniform
mixture cannot be held explicitly, so it is evaluated by a sweep: each update scores
``sweep_poses`` poses of a fixed pseudo-random tour of the whole grid with their share
``eps / |L|`` of prior, and those that explain the scan well enough join the held set. That is how
a kidnapped robot recovers (Table 1, "Recovery"). Swept poses are screened on a few beams first
and only the most promising get the full product of Eq. 2; a uniform belief (global localization)
is screened the same way down to ``max_active`` poses.

The filters judge each beam against the belief *with* its uniform part (sampled from the sweep): a
beam that only poses elsewhere explain (a person in front of the robot, seen by a pose next to a
wall) moves mass to the uniform part, raises the entropy and fails the entropy filter; without
this, a filtered-in reading would let the sweep pull the belief away from the truth.

The product of Eq. 2 is damped by the power ``k`` (:attr:`GridMarkovConfig.likelihood_power`,
0.1): the beams' errors are correlated, and the undamped product is so confident that a single
scan the map explains badly at the true pose hands the belief to a pose elsewhere.

The expected range of every beam is a table look-up: the project's ray caster fills, once per map,
the range from every free cell centre at every ``table_angle_step`` (1 degree by default, the
laser's beam spacing), so a beam of a pose in heading layer ``k`` reads
``table[cell, (k * angle_step + laser_yaw + beam_angle) / table_angle_step]``. The beam model's
``p(s_b | l)`` and ``p_n(s_b | l)`` (Eq. 5) are tabulated per scan over range bins. The hot loops
are the numba kernels of :mod:`tourbot.localization.grid_kernels`. The table is built on the
first update (seconds to a minute for a museum; :meth:`GridMarkovLocalization.prepare` builds it
ahead, with progress, and :meth:`~GridMarkovLocalization.use_table` shares it between localizers).
"""

from __future__ import annotations

import hashlib
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import relative, wrap_angle
from tourbot.localization import grid_kernels as gk
from tourbot.localization.beam_filters import BeamFilter, BeamFilterConfig
from tourbot.localization.errors import LocalizationError
from tourbot.localization.estimate import LocalizationEstimate
from tourbot.localization.motion_model import OdometryMotionModel, decompose
from tourbot.localization.range_table import ExpectedRangeTable
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import RangeCaster
from tourbot.records import LaserGeometry, Scan

__all__ = [
    "ExpectedRangeTable",
    "GridMarkovConfig",
    "GridMarkovError",
    "GridMarkovLocalization",
    "PoseLattice",
    "default_table_cache",
    "layer_kernels",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Progress = Callable[[int, int], None]


class GridMarkovError(LocalizationError):
    """A grid localizer used before it has a map, or given a map with no free space."""


def _default_caster(grid: OccupancyGrid, max_range: float, unknown_blocks: bool = True) -> RangeCaster:
    """The project's fastest exact caster."""
    from tourbot.maps.raycast import DistanceCaster

    return DistanceCaster(grid, max_range, unknown_blocks=unknown_blocks)


@dataclass(frozen=True)
class GridMarkovConfig:
    """Parameters of grid Markov localization.

    From Fox et al. 1998: ``cell_size`` 0.15 m and ``angle_step`` 2 degrees (Sec. "Markov
    localization"); ``beam_filter`` and the novelty threshold ``theta`` 0.99 (Sec. "Novelty
    filter", in :attr:`filters`). The paper's grid keeps a small uniform mixture for recovery
    but gives no value; ``uniform_mixture`` 0.01 is ours. The rest are choices of this
    implementation:

    - ``table_angle_step``: angular step of the expected-range table (1 degree: the laser's beam
      spacing, so neighbouring beams do not share a ray).
    - ``range_bin``: range resolution of the table and of the per-scan likelihood tables (m; a
      quarter of the beam model's ``sigma_hit``).
    - ``prune_ratio``: poses whose belief is below this fraction of the largest are dropped (the
      selective update); ``max_active`` caps how many are held.
    - ``sweep_poses``: poses of the uniform mixture scored per update (recovery). They are first
      screened on ``screen_beams`` of the used beams (evenly spread); only the ``screen_keep``
      best get the full Eq. 2 update, the rest count as negligible, like unswept poses.
    - ``filter_sample``: how many swept poses stand for the mixture when the filters judge beams.
    - ``min_translation``, ``min_rotation``: odometry is accumulated until the robot has moved
      half a cell or half a heading step, so slow motion is not rounded away.
    - ``motion_sigmas``: width of the motion kernel's window in standard deviations.
    - ``tracking_std``: the default spread of :meth:`GridMarkovLocalization.reset_tracking`.
    - ``unknown_blocks``: whether unknown cells stop the rays of the expected-range table. Yes
      for a map with its unknown cells only outside the observed space (the log's reference map;
      on FHW with likelihood_power 1.0, 12.3 cm mean error with the novelty filter, against 31.9 cm
      without); no for a trinary map_server map, whose uncertain cells come back unknown (first
      40 FHW scans through a PGM: 6 scans off by metres with, none without).
    - ``mode_radius``, ``mode_angle``: the estimate is the belief's mean within this distance of
      its most probable pose.
    - ``likelihood_power``: Eq. 2 takes the product of ``p(s_b | l)`` over the used beams as if
      they were independent; their errors are not (neighbouring beams share the map's errors, the
      crowd's bodies and the lattice's 15 cm x 2 deg rounding), so the product is overconfident
      by far. It may be raised to this power (Probabilistic Robotics Sec. 6.3.4 suggests such
      damping; the default 1 is the paper's plain product; the FHW profile's 0.1 is about one
      independent beam per 10 degrees). With the full product (1.0) the
      belief collapses to a handful of poses, and on a scan where the truth explains the beams a
      little worse than a pose elsewhere (readings *longer* than the map predicts, which no filter
      drops, or the few beams the crowd leaves), the recovery sweep takes the whole belief there:
      on FHW's peak crowd 6-10 % failures with the novelty filter (crowd seeds 0-1), against
      0.0-0.8 % at 0.1 (0.2: 0.0-1.4 %; 0.5: 0.8-2.0 %; tuned on crowd seeds 0 and 1 only).
    """

    cell_size: float = 0.15
    angle_step: float = math.radians(2.0)
    table_angle_step: float = math.radians(1.0)
    range_bin: float = 0.05
    beam_filter: BeamFilter = BeamFilter.NOVELTY
    filters: BeamFilterConfig = field(default_factory=BeamFilterConfig)
    uniform_mixture: float = 0.01
    prune_ratio: float = 1e-6
    max_active: int = 300_000
    sweep_poses: int = 100_000
    screen_beams: int = 24
    screen_keep: int = 1_000
    filter_sample: int = 2_000
    min_translation: float = 0.075
    min_rotation: float = math.radians(1.0)
    motion_sigmas: float = 3.0
    tracking_std: tuple[float, float, float] = (0.1, 0.1, math.radians(5.0))
    unknown_blocks: bool = True
    mode_radius: float = 0.5
    mode_angle: float = math.radians(20.0)
    likelihood_power: float = 1.0

    def __post_init__(self) -> None:
        for name in ("cell_size", "angle_step", "table_angle_step", "range_bin"):
            if not getattr(self, name) > 0:
                raise GridMarkovError(
                    f"grid Markov config: {name} must be positive, got {getattr(self, name)}"
                )
        if not 0.0 <= self.uniform_mixture < 1.0:
            raise GridMarkovError(
                f"grid Markov config: uniform_mixture must be in [0, 1), got {self.uniform_mixture}"
            )
        if not 0.0 < self.likelihood_power <= 1.0:
            raise GridMarkovError(
                f"grid Markov config: likelihood_power must be in (0, 1], got {self.likelihood_power}"
            )
        if not 0.0 <= self.prune_ratio < 1.0:
            raise GridMarkovError(
                f"grid Markov config: prune_ratio must be in [0, 1), got {self.prune_ratio}"
            )


@dataclass(frozen=True)
class PoseLattice:
    """The grid of poses: ``n_theta`` heading layers times the free position cells of a map.

    Position cells are ``cell_size`` squares laid out in the map's grid frame from its origin; a
    cell is free when the map cell under its centre is free. Pose ``(k, f)`` (heading layer ``k``,
    free cell ``f``) has the flat index ``k * n_free + f``; its heading is ``k * angle_step`` in the
    grid frame.
    """

    grid: OccupancyGrid
    cell_size: float
    angle_step: float
    n_theta: int
    free_rc: IntArray
    free_index: IntArray

    @classmethod
    def from_grid(cls, grid: OccupancyGrid, cell_size: float, angle_step: float) -> PoseLattice:
        n_theta = round(2.0 * math.pi / angle_step)
        if n_theta < 1 or abs(n_theta * angle_step - 2.0 * math.pi) > 1e-6:
            raise GridMarkovError(
                f"angle_step must divide 360 degrees, got {math.degrees(angle_step)} degrees"
            )
        rows = math.ceil(grid.height / cell_size - 1e-9)
        cols = math.ceil(grid.width / cell_size - 1e-9)
        rr, cc = np.mgrid[0:rows, 0:cols]
        mr = np.floor((rr + 0.5) * cell_size / grid.resolution).astype(np.int64)
        mc = np.floor((cc + 0.5) * cell_size / grid.resolution).astype(np.int64)
        free_map = grid.free()
        ok = (mr < grid.shape[0]) & (mc < grid.shape[1])
        free = np.zeros((rows, cols), dtype=bool)
        free[ok] = free_map[mr[ok], mc[ok]]
        free_rc = np.argwhere(free).astype(np.int64)
        if free_rc.shape[0] == 0:
            raise GridMarkovError("the map has no free cell to localize in")
        free_index = np.full((rows, cols), -1, dtype=np.int64)
        free_index[free_rc[:, 0], free_rc[:, 1]] = np.arange(free_rc.shape[0])
        return cls(grid, float(cell_size), float(2.0 * math.pi / n_theta), n_theta, free_rc, free_index)

    @property
    def n_free(self) -> int:
        return int(self.free_rc.shape[0])

    @property
    def n_poses(self) -> int:
        return self.n_theta * self.n_free

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of position cells."""
        return (int(self.free_index.shape[0]), int(self.free_index.shape[1]))

    def grid_poses(self, pose_idx: ArrayLike) -> FloatArray:
        """Poses ``(N, 3)`` of flat indices, in the map's grid frame (cell centres)."""
        p = np.asarray(pose_idx, dtype=np.int64)
        k, f = p // self.n_free, p % self.n_free
        rc = self.free_rc[f]
        return np.stack(
            [
                (rc[:, 1] + 0.5) * self.cell_size,
                (rc[:, 0] + 0.5) * self.cell_size,
                wrap_angle(k * self.angle_step),
            ],
            axis=-1,
        )

    def poses(self, pose_idx: ArrayLike) -> FloatArray:
        """World poses ``(N, 3)`` of flat indices (cell centres)."""
        return self.grid.grid_to_world(self.grid_poses(pose_idx))

    def index_of(self, poses: ArrayLike) -> IntArray:
        """Flat indices ``(N,)`` of the cells holding world poses ``(N, 3)``; -1 where not free."""
        g = self.grid.world_to_grid(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
        c = np.floor(g[:, 0] / self.cell_size).astype(np.int64)
        r = np.floor(g[:, 1] / self.cell_size).astype(np.int64)
        k = np.round(g[:, 2] / self.angle_step).astype(np.int64) % self.n_theta
        rows, cols = self.shape
        inside = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        f = np.full(r.shape, -1, dtype=np.int64)
        f[inside] = self.free_index[r[inside], c[inside]]
        return np.where(f >= 0, k * self.n_free + f, -1)


def _cast_table(
    lattice: PoseLattice,
    caster: RangeCaster,
    max_range: float,
    angle_step: float,
    range_bin: float,
    progress: Progress | None = None,
) -> ExpectedRangeTable:
    """The expected-range table of every free cell centre of ``lattice``, at grid-frame angles."""
    n_angles = round(2.0 * math.pi / angle_step)
    step = 2.0 * math.pi / n_angles
    centres = lattice.grid_poses(np.arange(lattice.n_free))
    centres[:, 2] = 0.0
    world = lattice.grid.grid_to_world(centres)
    return ExpectedRangeTable.cast(
        world, np.arange(n_angles, dtype=np.float64) * step, caster, max_range, range_bin, progress
    )


def default_table_cache() -> Path:
    """Where :meth:`GridMarkovLocalization.prepare` keeps expected-range tables by default:
    ``$XDG_CACHE_HOME/tourbot/grid-tables`` (``~/.cache/tourbot/grid-tables``)."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "tourbot" / "grid-tables"


def table_key(lattice: PoseLattice, config: GridMarkovConfig, max_range: float) -> str:
    """A digest of everything an expected-range table depends on: the map (cells, resolution,
    origin, thresholds), the lattice, the table's angular step and range bins, ``max_range`` and
    whether unknown cells block rays. Tables of the default caster only."""
    g = lattice.grid
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(g.prob).tobytes())
    h.update(np.asarray(g.prob.shape, dtype=np.int64).tobytes())
    numbers = (
        g.resolution, *g.origin, g.occupied_thresh, g.free_thresh, lattice.cell_size, lattice.angle_step,
        config.table_angle_step, config.range_bin, max_range, float(config.unknown_blocks),
    )  # fmt: skip
    h.update(np.asarray(numbers, dtype=np.float64).tobytes())
    return h.hexdigest()[:24]


@dataclass
class _BeamLayout:
    """Where each beam of a laser reads the table, per heading layer (cached per laser geometry)."""

    beam_cols: IntArray  # (n_theta, B) table column of beam b in heading layer k
    laser_shift: IntArray  # (n_theta, 2) (row, col) offset of the laser's cell from the robot's


class GridMarkovLocalization:
    """Markov localization on a 15 cm x 2 deg position probability grid (Fox et al. 1998, Eq. 1-6).

    ``reset_global`` spreads the belief uniformly over the free poses; ``reset_tracking`` puts a
    Gaussian around a known pose; ``update(odom_pose, scan)`` runs one motion + sensor step and
    answers a :class:`~tourbot.localization.estimate.LocalizationEstimate` whose ``used_beams`` are
    the beams that passed the filter. ``belief()`` and ``belief_map()`` give the belief for drawing.
    """

    def __init__(
        self,
        grid: OccupancyGrid | None = None,
        config: GridMarkovConfig | None = None,
        motion_model: OdometryMotionModel | None = None,
        sensor_model: BeamModel | None = None,
        caster_factory: Callable[[OccupancyGrid, float], RangeCaster] | None = None,
        table: ExpectedRangeTable | None = None,
    ) -> None:
        self.config = config or GridMarkovConfig()
        self.motion_model = motion_model or OdometryMotionModel()
        self.sensor_model = sensor_model or BeamModel()
        self._caster_factory = caster_factory
        self._lattice: PoseLattice | None = None
        self._table: ExpectedRangeTable | None = None
        self._layouts: dict[LaserGeometry, _BeamLayout] = {}
        self._dense = np.zeros(0)
        self._idx = np.zeros(0, dtype=np.int64)
        self._w = np.zeros(0)
        self._uniform = False
        self._odom_ref: FloatArray | None = None
        self._sweep_next = 0
        self._sweep_stride = 1
        self.table_source = ""
        if grid is not None:
            self.set_map(grid)
        if table is not None:
            self.use_table(table)

    # -------------------------------------------------------------------------------- map, tables

    def set_map(self, grid: OccupancyGrid) -> None:
        """Lay the pose lattice on ``grid`` (the expected-range table is built on first use)."""
        cfg = self.config
        self._lattice = PoseLattice.from_grid(grid, cfg.cell_size, cfg.angle_step)
        self._table = None
        self._layouts = {}
        self._dense = np.zeros(self._lattice.n_poses)
        self._sweep_stride = _coprime_stride(self._lattice.n_poses)
        self._sweep_next = 0
        self._idx = np.zeros(0, dtype=np.int64)
        self._w = np.zeros(0)

    @property
    def lattice(self) -> PoseLattice:
        if self._lattice is None:
            raise GridMarkovError("the grid localizer has no map: call reset_global(grid) or set_map(grid)")
        return self._lattice

    @property
    def table(self) -> ExpectedRangeTable | None:
        """The expected-range table, once built."""
        return self._table

    def use_table(self, table: ExpectedRangeTable) -> None:
        """Reuse an expected-range table built for the same map and configuration (it is costly)."""
        lat = self.lattice
        if table.bins.shape[0] != lat.n_free or not math.isclose(table.range_bin, self.config.range_bin):
            raise GridMarkovError(
                f"the expected-range table ({table.bins.shape[0]} cells, {table.range_bin} m bins) does not "
                f"fit this map's lattice ({lat.n_free} cells, {self.config.range_bin} m bins)"
            )
        if not math.isclose(table.angle_step, self.config.table_angle_step):
            raise GridMarkovError("the expected-range table has another angular step than the configuration")
        self._table = table

    def prepare(
        self, max_range: float, progress: Progress | None = None, cache: Path | None = None
    ) -> ExpectedRangeTable:
        """Build (once per map and maximum range) the expected-range table by ray casting.

        With ``cache`` (a directory) and the default caster, the table is read from there when a
        table of the same map and parameters (:func:`table_key`) was saved before, and saved
        there after it is built; :attr:`table_source` says which happened.
        """
        lat = self.lattice
        if self._table is None or self._table.max_range != max_range:
            cfg = self.config
            path = None
            if cache is not None and self._caster_factory is None:
                path = cache / f"{table_key(lat, cfg, max_range)}.npz"
                if path.exists():
                    try:
                        self.use_table(ExpectedRangeTable.load(path))
                        self.table_source = f"read from {path}"
                        return self._table  # type: ignore[return-value]
                    except LocalizationError:
                        pass  # unreadable or stale: build it again and overwrite
            if self._caster_factory is None:
                caster = _default_caster(lat.grid, max_range, cfg.unknown_blocks)
            else:
                caster = self._caster_factory(lat.grid, max_range)
            table = _cast_table(lat, caster, max_range, cfg.table_angle_step, cfg.range_bin, progress)
            self._table = table
            self.table_source = "built"
            if path is not None:
                try:
                    table.save(path)
                    self.table_source = f"built and saved to {path}"
                except OSError as exc:
                    self.table_source = f"built (not saved to {path}: {exc.strerror})"
        return self._table

    def _layout(self, geometry: LaserGeometry, table: ExpectedRangeTable) -> _BeamLayout:
        layout = self._layouts.get(geometry)
        if layout is None:
            lat = self.lattice
            heads = np.arange(lat.n_theta) * lat.angle_step
            ox, oy, oth = geometry.offset
            a = heads[:, None] + oth + geometry.angles[None, :]
            cols = np.round(a / table.angle_step).astype(np.int64) % table.n_angles
            sx = np.cos(heads) * ox - np.sin(heads) * oy
            sy = np.sin(heads) * ox + np.cos(heads) * oy
            shift = np.stack([np.round(sy / lat.cell_size), np.round(sx / lat.cell_size)], axis=-1)
            layout = _BeamLayout(np.ascontiguousarray(cols), shift.astype(np.int64))
            self._layouts[geometry] = layout
        return layout

    # -------------------------------------------------------------------------------- resets

    def reset_global(self, grid: OccupancyGrid | None = None) -> None:
        """Global localization: ``Bel(l)`` uniform over every free pose of the grid."""
        if grid is not None:
            self.set_map(grid)
        lat = self.lattice
        self._idx = np.arange(lat.n_poses, dtype=np.int64)
        self._w = np.full(lat.n_poses, 1.0 / lat.n_poses)
        self._uniform = True
        self._odom_ref = None
        self._sweep_next = 0  # a reset localizer runs as a fresh one

    def reset_tracking(
        self, pose: ArrayLike, cov: ArrayLike | None = None, grid: OccupancyGrid | None = None
    ) -> None:
        """Tracking: ``Bel(l)`` a Gaussian of covariance ``cov (3, 3)`` around the world ``pose``.

        ``cov`` defaults to ``diag(tracking_std**2)`` (10 cm, 10 cm, 5 deg, as MCL's).
        Evaluated at cell centres within ``4`` standard deviations; the spread is floored at half
        a cell and half a heading step so the belief is never empty.
        """
        if grid is not None:
            self.set_map(grid)
        lat = self.lattice
        mu = np.asarray(pose, dtype=np.float64).reshape(3)
        c = np.diag(np.square(self.config.tracking_std)) if cov is None else np.asarray(cov, np.float64)
        c = c.reshape(3, 3)
        c = c + np.diag([(lat.cell_size / 2) ** 2, (lat.cell_size / 2) ** 2, (lat.angle_step / 2) ** 2])
        centres = lat.poses(np.arange(lat.n_free))[:, :2]
        reach = 4.0 * math.sqrt(max(c[0, 0], c[1, 1]))
        near = np.flatnonzero(np.hypot(centres[:, 0] - mu[0], centres[:, 1] - mu[1]) <= reach + lat.cell_size)
        layers = np.arange(lat.n_theta)
        idx = (layers[:, None] * lat.n_free + near[None, :]).ravel()
        poses = lat.poses(idx)
        d = poses - mu
        d[:, 2] = wrap_angle(d[:, 2])
        q = np.einsum("ni,ij,nj->n", d, np.linalg.inv(c), d)
        keep = q <= 16.0
        if not keep.any():
            raise GridMarkovError(f"reset_tracking: no free cell near the pose {mu.tolist()}")
        self._idx = idx[keep].astype(np.int64)
        w = np.exp(-0.5 * q[keep])
        self._w = w / w.sum()
        self._uniform = False
        self._odom_ref = None
        self._sweep_next = 0

    # -------------------------------------------------------------------------------- update

    def update(self, odom_pose: ArrayLike, scan: Scan) -> LocalizationEstimate:
        """One step of Markov localization: motion (Eq. 1), filters (Eq. 3-6), sensor (Eq. 2)."""
        t0 = time.perf_counter()
        if self._idx.size == 0:
            raise GridMarkovError(
                "the grid localizer has no belief: call reset_global or reset_tracking first"
            )
        table = self.prepare(scan.geometry.max_range)
        odom = np.asarray(odom_pose, dtype=np.float64).reshape(3)
        moved = self.predict(odom)  # Eq. 1
        used, info = self._sensor_update(scan, table)  # Eq. 2-6 and the uniform mixture
        info["motion_applied"] = float(moved)
        pose, cov = self._estimate()
        return LocalizationEstimate(
            timestamp=scan.timestamp,
            pose=pose,
            covariance=cov,
            used_beams=used,
            n_samples=int(self._idx.size),
            updated=True,
            update_seconds=time.perf_counter() - t0,
            info=info,
        )

    @property
    def odometry_reference(self) -> FloatArray | None:
        """The odometry pose of the last motion step (motion since then is held back)."""
        return self._odom_ref

    def predict(self, odom: FloatArray) -> bool:
        """Eq. 1 on the held poses, once the odometry has moved enough since the last motion step
        (half a cell or half a heading step); returns whether the belief moved."""
        cfg = self.config
        if self._odom_ref is None:
            self._odom_ref = odom
            return False
        d = relative(self._odom_ref, odom)
        if math.hypot(d[0], d[1]) < cfg.min_translation and abs(d[2]) < cfg.min_rotation:
            return False
        ref, self._odom_ref = self._odom_ref, odom
        if self._uniform:
            return True  # a uniform belief stays uniform under the motion model
        weights, offsets = self.motion_kernels(ref, odom)
        lat = self.lattice
        touched = gk.motion_scatter(
            self._idx,
            self._w,
            lat.n_theta,
            lat.n_free,
            lat.free_rc,
            lat.free_index,
            weights,
            offsets,
            self._dense,
        )
        idx, w = gk.collect(touched, self._dense, cfg.prune_ratio)
        if w.size == 0 or not w.sum() > 0:
            # everything moved into obstacles: keep the belief where it was rather than lose it
            return True
        self._idx, self._w = idx, w / w.sum()
        return True

    def motion_kernels(self, odom_prev: ArrayLike, odom_now: ArrayLike) -> tuple[FloatArray, IntArray]:
        """The convolution form of the motion model for every heading layer (see :func:`layer_kernels`)."""
        lat = self.lattice
        heads = np.arange(lat.n_theta) * lat.angle_step
        return layer_kernels(
            self.motion_model,
            odom_prev,
            odom_now,
            lat.cell_size,
            lat.angle_step,
            heads,
            self.config.motion_sigmas,
        )

    def _sensor_tables(
        self, ranges: FloatArray, valid: NDArray[np.bool_], table: ExpectedRangeTable
    ) -> tuple[FloatArray, FloatArray]:
        """``log p(s_b | z*)`` and ``p_n(s_b | z*)`` (Eq. 5) per beam and range bin, ``(B, n_bins)``.

        From the project's beam model; rows of beams that are not ``valid`` are left at zero.
        """
        expected = (np.arange(table.n_bins, dtype=np.float64) * table.range_bin).astype(np.float32)
        beams = np.flatnonzero(valid)
        e = np.broadcast_to(expected[:, None], (table.n_bins, beams.size))
        ll = np.zeros((ranges.shape[0], table.n_bins))
        ps = np.zeros((ranges.shape[0], table.n_bins))
        if beams.size:
            p = self.sensor_model.probabilities(e, ranges[beams], table.max_range)
            ll[beams] = self.config.likelihood_power * np.log(np.maximum(p, 1e-300)).T
            ps[beams] = self.sensor_model.prob_shorter(e, ranges[beams], table.max_range).T
        return ll, ps

    def _sensor_update(
        self, scan: Scan, table: ExpectedRangeTable
    ) -> tuple[NDArray[np.bool_], dict[str, float]]:
        cfg = self.config
        lat = self.lattice
        geometry = scan.geometry
        layout = self._layout(geometry, table)
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        valid = np.isfinite(ranges) & (ranges >= geometry.min_range) & (ranges < geometry.max_range)
        ranges = np.where(np.isfinite(ranges), ranges, geometry.max_range)
        ll, ps = self._sensor_tables(ranges, valid, table)
        args = (lat.n_free, lat.free_rc, lat.free_index, layout.laser_shift, table.bins, layout.beam_cols)
        info: dict[str, float] = {}

        # The uniform mixture: its share of the prior, and the poses of it scored this time, each
        # standing for n_background / n_swept poses of the mixture.
        eps = cfg.uniform_mixture if not self._uniform else 0.0
        u = eps / lat.n_poses
        sweep = self._sweep_candidates() if eps > 0 else np.zeros(0, dtype=np.int64)
        held, prior_a = self._idx, (1.0 - eps) * self._w + u
        sample = _every(sweep, cfg.filter_sample)
        stands_for = (lat.n_poses - held.size) / sample.size if sample.size else 0.0
        # A uniform belief (global localization) is judged on a sample of itself.
        judged = _every(np.arange(held.size), cfg.filter_sample) if self._uniform else np.arange(held.size)

        # Eq. 3-6: judge every beam against the current belief, uniform mixture included (so a
        # beam that only a pose elsewhere explains raises the entropy and fails the entropy filter).
        used = valid.copy()
        if cfg.beam_filter != BeamFilter.NONE and valid.any():
            dh, pn = gk.filter_statistics(
                np.concatenate([held[judged], sample]),
                np.concatenate([prior_a[judged], np.full(sample.size, u)]),
                np.concatenate(
                    [np.full(judged.size, held.size / judged.size), np.full(sample.size, stands_for)]
                ),
                *args,
                np.flatnonzero(valid),
                ll,
                ps,
            )
            if cfg.beam_filter == BeamFilter.ENTROPY:
                used &= dh >= -cfg.filters.entropy_tolerance
            else:
                used &= pn <= cfg.filters.theta
        info["valid_beams"] = float(valid.sum())
        if not used.any():
            return used, info

        # Screen the swept poses (and a uniform belief's poses) on a few beams, keep the best;
        # Eq. 2 on the held poses and the kept swept ones.
        few = np.zeros_like(used)
        few[_every(np.flatnonzero(used), cfg.screen_beams)] = True
        sweep = self._screen(sweep, cfg.screen_keep, few, ll, args)
        if self._uniform:
            keep_held = self._screen(np.arange(held.size), cfg.max_active, few, ll, args, held)
            held, prior_a = held[keep_held], prior_a[keep_held]
        ll_a = gk.scan_log_likelihood(held, *args, used, ll)
        ll_s = gk.scan_log_likelihood(sweep, *args, used, ll)
        top = max(ll_a.max(), ll_s.max() if ll_s.size else -np.inf)
        post_a = prior_a * np.exp(ll_a - top)
        post_s = u * np.exp(ll_s - top)
        z = post_a.sum() + post_s.sum()
        info["sweep_mass"] = float(post_s.sum() / z)
        idx = np.concatenate([held, sweep])
        w = np.concatenate([post_a, post_s]) / z
        keep = w >= cfg.prune_ratio * w.max()
        idx, w = idx[keep], w[keep]
        if idx.size > cfg.max_active:
            top_k = np.argpartition(w, -cfg.max_active)[-cfg.max_active :]
            idx, w = idx[top_k], w[top_k]
        self._idx, self._w = idx, w / w.sum()
        self._uniform = False
        info["swept"] = float(sweep.size)
        return used, info

    @staticmethod
    def _screen(
        items: IntArray,
        keep: int,
        few: NDArray[np.bool_],
        ll: FloatArray,
        args: tuple[int, IntArray, IntArray, IntArray, NDArray[np.uint16], IntArray],
        poses: IntArray | None = None,
    ) -> IntArray:
        """The ``keep`` items whose poses (``poses[items]``, or the items themselves) score best on
        the beams ``few``, in increasing order; all of them when there are no more than ``keep``."""
        if items.size <= keep:
            return items
        pose_idx = items if poses is None else poses[items]
        partial = gk.scan_log_likelihood(pose_idx, *args, few, ll)
        return np.sort(items[np.argpartition(partial, -keep)[-keep:]])

    def _sweep_candidates(self) -> IntArray:
        """The next ``sweep_poses`` poses of a fixed pseudo-random tour of the grid, not held now.

        The tour runs over ``cell * n_theta + heading`` so that, once sorted, consecutive poses read
        the same rows of the range table.
        """
        lat = self.lattice
        n = lat.n_poses
        m = min(self.config.sweep_poses, n)
        if m <= 0:
            return np.zeros(0, dtype=np.int64)
        steps = (self._sweep_next + np.arange(m, dtype=np.int64)) % n
        self._sweep_next = int((self._sweep_next + m) % n)
        tour = np.sort((steps * self._sweep_stride) % n)
        cand = (tour % lat.n_theta) * lat.n_free + tour // lat.n_theta
        held = np.sort(self._idx)
        at = np.minimum(np.searchsorted(held, cand), max(held.size - 1, 0))
        return cand[held[at] != cand] if held.size else cand

    # -------------------------------------------------------------------------------- estimate

    def _estimate(self) -> tuple[FloatArray, FloatArray]:
        """The mean of the most probable mode, and the covariance of the whole belief about it."""
        cfg = self.config
        poses = self.lattice.poses(self._idx)
        w = self._w
        best = poses[int(np.argmax(w))]
        d = poses - best
        d[:, 2] = wrap_angle(d[:, 2])
        near = (np.hypot(d[:, 0], d[:, 1]) <= cfg.mode_radius) & (np.abs(d[:, 2]) <= cfg.mode_angle)
        wn = w[near] / w[near].sum()
        mean = np.array(
            [
                wn @ poses[near, 0],
                wn @ poses[near, 1],
                math.atan2(float(wn @ np.sin(poses[near, 2])), float(wn @ np.cos(poses[near, 2]))),
            ]
        )
        d = poses - mean
        d[:, 2] = wrap_angle(d[:, 2])
        cov = (d * w[:, None]).T @ d
        return mean, np.asarray(cov, dtype=np.float64)

    # -------------------------------------------------------------------------------- drawing

    def belief(self) -> tuple[FloatArray, FloatArray]:
        """The held poses as world poses ``(N, 3)`` and their belief ``(N,)`` (sums to one)."""
        return self.lattice.poses(self._idx), self._w.copy()

    def belief_map(self) -> FloatArray:
        """The belief summed over headings, ``(rows, cols)`` of position cells (for drawing)."""
        lat = self.lattice
        per_cell = np.bincount(self._idx % lat.n_free, weights=self._w, minlength=lat.n_free)
        out = np.zeros(lat.shape)
        out[lat.free_rc[:, 0], lat.free_rc[:, 1]] = per_cell
        return out

    def entropy(self) -> float:
        """Eq. 3 over the held poses, nats."""
        w = self._w[self._w > 0]
        return float(-(w * np.log(w)).sum())


def layer_kernels(
    model: OdometryMotionModel,
    odom_prev: ArrayLike,
    odom_now: ArrayLike,
    resolution: float,
    angular_resolution: float,
    headings: ArrayLike,
    n_sigma: float = 3.0,
    floor_std_cells: float = 0.5,
) -> tuple[FloatArray, IntArray]:
    """:meth:`OdometryMotionModel.kernel` for many heading layers at once, padded to one shape.

    Eq. 1's ``p(l | l', a)`` on the grid: for each heading (grid frame) the Gaussian of the
    odometry model (Probabilistic Robotics Table 5.6, propagated to ``(x, y, theta)``), centred on
    the mean displacement, evaluated at cell centres over ``n_sigma`` standard deviations and
    normalized. The spread is floored at ``floor_std_cells`` (half a cell by default: with less, a
    Gaussian sampled at cell centres rounds a sub-cell shift to the nearest cell and the belief
    drifts by up to half a cell per step). With ``floor_std_cells=0.25`` these are the numbers of
    ``model.kernel`` per layer (a test checks it), without ``n_theta`` Python calls per update.
    Returns ``weights (K, Kt, Kr, Kc)`` (zero beyond each layer's own window) and ``offsets (K, 3)``.
    """
    rot1, trans, rot2 = decompose(odom_prev, odom_now)
    s = np.array(model.stds(rot1, trans, rot2))
    h = np.asarray(headings, dtype=np.float64)
    a = h + rot1
    n = h.shape[0]
    J = np.zeros((n, 3, 3))
    J[:, 0, 0] = -trans * np.sin(a)
    J[:, 0, 1] = np.cos(a)
    J[:, 1, 0] = trans * np.cos(a)
    J[:, 1, 1] = np.sin(a)
    J[:, 2, 0] = 1.0
    J[:, 2, 2] = 1.0
    cov_xyt = np.einsum("nij,j,nkj->nik", J, s**2, J)
    order = [2, 1, 0]  # (x, y, theta) -> (theta, row = y, col = x), in cells
    scale = np.array([angular_resolution, resolution, resolution])
    cov = cov_xyt[:, order][:, :, order] / np.outer(scale, scale)[None]
    cov = cov + np.diag(np.full(3, floor_std_cells**2))[None]
    mean = np.stack(
        [
            np.full(n, (rot1 + rot2) / angular_resolution),
            trans * np.sin(a) / resolution,
            trans * np.cos(a) / resolution,
        ],
        axis=-1,
    )
    std = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
    lo = np.floor(mean - n_sigma * std).astype(np.int64)
    hi = np.ceil(mean + n_sigma * std).astype(np.int64)
    size = (hi - lo + 1).max(axis=0)
    axes = [np.arange(size[i])[None, :] + lo[:, i : i + 1] - mean[:, i : i + 1] for i in range(3)]
    d = np.stack(
        np.broadcast_arrays(axes[0][:, :, None, None], axes[1][:, None, :, None], axes[2][:, None, None, :]),
        axis=-1,
    )  # (K, Kt, Kr, Kc, 3) offsets from the mean, in cells
    inv = np.linalg.inv(cov)
    flat = d.reshape(n, -1, 3)
    q = np.sum((flat @ inv) * flat, axis=-1).reshape(d.shape[:-1])  # Mahalanobis distances
    w = np.exp(-0.5 * q)
    inside = [np.arange(size[i])[None, :] <= (hi - lo)[:, i : i + 1] for i in range(3)]
    w *= inside[0][:, :, None, None] & inside[1][:, None, :, None] & inside[2][:, None, None, :]
    w /= w.sum(axis=(1, 2, 3), keepdims=True)
    return w, lo


def _every(items: NDArray[Any], count: int) -> NDArray[Any]:
    """About ``count`` items evenly spread over ``items`` (all of them if there are fewer)."""
    step = max(1, -(-items.size // max(count, 1)))
    return items[::step]


def _coprime_stride(n: int) -> int:
    """A stride coprime to ``n`` near ``0.618 n``: ``(i * stride) mod n`` tours all of ``0..n-1``."""
    s = max(1, int(n * 0.6180339887))
    while math.gcd(s, n) != 1:
        s += 1
    return s
