"""Obstacles the laser misses, from two images and the laser (Burgard et al., Sec. 3; Baltzakis et
al. 2002): read :meth:`VisionDetector.detect` first.

1. the 2.5D model of scan ``s_{t-1}`` (vertical walls through its endpoints, floor elsewhere) gives
   every pixel of image ``t`` a world point; image ``i_{t-1}`` sampled there is ``î_t``
   (``tourbot.vision.model``), with the robot's motion between the images;
2. local correlation of ``î_t`` and ``i_t`` (``tourbot.vision.correlation``): where they disagree
   and both are textured, the model is wrong there: something the laser missed;
3. each inconsistent pixel is taken along its epipolar line: the depths along its ray from camera
   ``t`` are tried in image ``t-1`` and the best-matching one (patch NCC) gives the obstacle's 3D
   point, kept when it lies in front of the model's surface, between the floor and the robot's
   height, within ``max_distance``, and away from every laser endpoint (what the laser sees is
   the laser's);
4. visitors leave no phantom: the people tracker's estimates (Burgard et al., Sec. 4) at each
   image's time are upright bodies (:func:`body_mask`); a pixel of image t on a body, a pixel of
   ``î_t`` sampled from a body in image t-1, and an epipolar candidate that falls on a body in
   image t-1 are not used (a track on laser returns all narrower than a leg is a table's legs
   and masks nothing); visitors the tracker has not yet taken up are masked by the laser
   alone (endpoints of ``s_t`` with no endpoint of ``s_{t-1}`` near them, and the other way round:
   the image columns of their bodies). The floor points where the images agree are returned too
   (free space for the map).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from tourbot.geometry import wrap_angle
from tourbot.vision.camera import ForwardCamera
from tourbot.vision.correlation import local_ncc, patch_ncc
from tourbot.vision.model import back_project, model_points, model_profile

__all__ = ["Detection", "View", "VisionConfig", "VisionDetector", "body_mask"]

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]


@dataclass(frozen=True)
class VisionConfig:
    """Parameters of the detector (the paper gives none; these are tourbot's, at 640 x 480).

    ``window``: NCC window (px); ``inconsistent``: NCC below this is a disagreement, ``agree``: NCC
    above this is agreement; ``min_std``: texture both images need (counts); ``stride``: the
    epipolar search runs on every ``stride``-th pixel in each direction; ``depths``: depths tried
    along each ray; ``patch``: the search's patch (px); ``match``: NCC the best depth needs,
    ``margin``: by how much it beats the model's depth, ``unique``: and every depth three steps or
    more from it;
    ``max_pixels``: at most this many searches per image; ``max_inconsistent``: a pair where more
    of the textured pixels disagree is dropped (the motion is wrong, not the model); ``max_shift``:
    the largest residual shift (px) taken out between the images; ``max_gap``: endpoints farther apart
    are not joined by a wall; ``min_distance``/``max_distance``: horizontal range of detections
    (m); ``in_front``: how far in front of the model's surface a detection must lie (m);
    ``laser_explains``: a detection this close to a laser endpoint is the laser's (m);
    ``min_height``/``max_height``: the heights that matter to the robot (m); ``min_parallax``: the
    smallest angle between the two cameras' rays to a detection (rad: near the epipole of a forward
    motion depth is not determined); ``moving``: a laser
    endpoint this far from every endpoint of the other scan moved (m); ``body``: half width of a
    visitor's body around a moving endpoint (m); ``min_leg``: a run of endpoints narrower than
    this is no visitor's leg (a table leg) and masks nothing (m); ``azimuth_step``: resolution of the model's
    range profile (rad); ``person_radius``/``person_height``: the upright body (m) masked around each of
    the tracker's visitors (a body's half width, about 0.22 m, and the track's error, about 0.12 m
    on FHW's peak crowd)."""

    window: int = 9
    inconsistent: float = 0.5
    agree: float = 0.85
    min_std: float = 5.0
    stride: int = 4
    depths: int = 24
    patch: int = 5
    match: float = 0.85
    margin: float = 0.1
    unique: float = 0.05
    max_pixels: int = 1000
    max_inconsistent: float = 0.3
    max_shift: float = 10.0
    max_gap: float = 0.5
    min_distance: float = 0.6
    max_distance: float = 3.0
    in_front: float = 0.2
    laser_explains: float = 0.15
    min_height: float = 0.04
    max_height: float = 1.3
    min_parallax: float = math.radians(0.3)
    moving: float = 0.15
    body: float = 0.35
    min_leg: float = 0.07
    azimuth_step: float = math.radians(0.1)
    person_radius: float = 0.35
    person_height: float = 2.0


@dataclass(frozen=True)
class View:
    """One image with what was known when it was taken: the robot's ``pose`` (world, from the
    estimate), the laser's endpoints ``(B, 2)`` (world) with which of them returned, and the
    visitors ``people`` ``(N, 2)`` (world) the people tracker estimates at that time."""

    image: NDArray[np.uint8]
    pose: FloatArray
    endpoints: FloatArray
    returned: NDArray[np.bool_]
    people: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass(frozen=True)
class Detection:
    """What one image pair gave: ``obstacles`` ``(K, 2)`` world points (with their ``heights`` and
    the ``pixels`` ``(K, 2)`` of image t they were seen at), ``floor`` ``(F, 2)`` world points the
    images agree on, ``inconsistent`` ``(H, W)`` the disagreeing pixels, ``masked`` the pixels of
    moving visitors."""

    obstacles: FloatArray
    heights: FloatArray
    pixels: NDArray[np.int64]
    floor: FloatArray
    inconsistent: NDArray[np.bool_]
    masked: NDArray[np.bool_]


class VisionDetector:
    """Finds what the laser misses in pairs of :class:`View` s (see the module docstring)."""

    def __init__(self, camera: ForwardCamera, config: VisionConfig | None = None) -> None:
        self.camera = camera
        self.config = cfg = config or VisionConfig()
        self._n_az = round(2 * math.pi / cfg.azimuth_step)
        self._azimuths: FloatArray = -math.pi + cfg.azimuth_step * np.arange(self._n_az, dtype=np.float64)
        self._rays = camera.rays.astype(np.float32)
        # a ray's horizontal length and vertical part do not change as the robot turns, its
        # azimuth turns with the robot: all three once, in the robot frame
        robot = camera.rays @ camera.mount_rotation.T
        self._az = np.asarray(np.arctan2(robot[..., 1], robot[..., 0]), dtype=np.float64)
        self._h = np.hypot(robot[..., 0], robot[..., 1])
        self._dz = robot[..., 2]
        lo, hi = float(self._az.min()), float(self._az.max())
        self._fov = (lo - 0.05, hi + 0.05)
        self._hann: Float32Array | None = None
        half = cfg.patch // 2
        oy, ox = np.mgrid[-half : half + 1, -half : half + 1]
        self._offsets = np.stack([ox.ravel(), oy.ravel()], axis=-1).astype(np.float32)

    def detect(self, prev: View, cur: View) -> Detection:
        """Obstacles seen in ``cur`` that the model of ``prev``'s scan does not explain."""
        cfg = self.config
        cam = self.camera
        m = cam.model
        rot_p, pos_p = cam.in_world(prev.pose)
        rot_c, pos_c = cam.in_world(cur.pose)
        rays = self._rays @ rot_c.T.astype(np.float32)
        # 1. the 2.5D model of s_{t-1} seen from camera t, and i_{t-1} back-projected through it
        th = float(cur.pose[2])
        az = wrap_angle(self._az + th)
        seen = _in_arc(self._azimuths, th + self._fov[0], th + self._fov[1])
        profile = np.full(self._n_az, np.inf)
        profile[seen] = model_profile(
            prev.endpoints, prev.returned, pos_c[:2], self._azimuths[seen], cfg.max_gap
        )
        t_model, on_floor = model_points(az, self._h, self._dz, float(pos_c[2]), profile, cfg.azimuth_step)
        points = pos_c.astype(np.float32) + rays * t_model[..., None]
        finite = np.isfinite(t_model)
        points[~finite] = 0.0
        warped, valid = back_project(prev.image, points, rot_p, pos_p, m.fx, m.fy, m.cx, m.cy)
        valid &= finite
        # the tracker's visitors: on a body in image t, or sampled from a body in image t-1
        body_prev = body_mask(
            self._rays @ rot_p.T.astype(np.float32),
            pos_p,
            self._visitors(prev),
            cfg.person_radius,
            cfg.person_height,
        )
        body = body_mask(rays, pos_c, self._visitors(cur), cfg.person_radius, cfg.person_height)
        from_body = np.zeros_like(body)
        if body_prev.any():
            sampled, _ = back_project(
                body_prev.astype(np.uint8), points, rot_p, pos_p, m.fx, m.fy, m.cx, m.cy
            )
            from_body = sampled > 0.0
        # the estimated motion is a little off (the odometry's turn above all): the residual shift of
        # the floor between the two images, by phase correlation, is taken out
        current = cur.image.astype(np.float32)
        shift = self._residual_shift(warped, current, valid)
        if shift != (0.0, 0.0):
            import cv2

            move = np.array([[1.0, 0.0, shift[0]], [0.0, 1.0, shift[1]]])
            flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
            warped = np.asarray(
                cv2.warpAffine(
                    warped, move, warped.shape[::-1], flags=flags, borderMode=cv2.BORDER_REPLICATE
                ),
                dtype=np.float32,
            )
            valid = cv2.warpAffine(valid.astype(np.uint8), move, valid.shape[::-1], flags=flags) > 0
            if from_body.any():
                from_body = (
                    cv2.warpAffine(from_body.astype(np.uint8), move, from_body.shape[::-1], flags=flags) > 0
                )
        body |= from_body
        # 2. local correlation: disagreement where both are textured
        ncc, s_warp, s_cur = local_ncc(warped, current, cfg.window)
        textured = (s_warp >= cfg.min_std) & (s_cur >= cfg.min_std) & valid
        masked = self._moving_mask(prev, cur, az, pos_c) | body
        inconsistent = textured & (ncc < cfg.inconsistent) & ~masked
        agree = textured & (ncc > cfg.agree) & ~masked & on_floor
        if inconsistent.sum() > cfg.max_inconsistent * max(int(textured.sum()), 1):
            # most of the image disagrees: the motion is wrong (a slip, a bump), not the model
            none = np.zeros((0, 2))
            return Detection(none, np.zeros(0), np.zeros((0, 2), dtype=np.int64), none, inconsistent, masked)
        # 3. along the epipolar lines
        obstacles, heights, pixels = self._search(
            prev, cur, inconsistent, rays, pos_c, t_model, rot_p, pos_p, shift, body_prev
        )
        s = cfg.stride
        sub = np.zeros_like(agree)
        sub[::s, ::s] = True
        fl = points[agree & sub][:, :2].astype(np.float64)
        near = np.hypot(fl[:, 0] - pos_c[0], fl[:, 1] - pos_c[1]) <= cfg.max_distance
        return Detection(obstacles, heights, pixels, fl[near], inconsistent, masked)

    def _residual_shift(
        self, warped: Float32Array, current: Float32Array, valid: NDArray[np.bool_]
    ) -> tuple[float, float]:
        """The shift ``(du, dv)`` (px) of image t against ``î_t`` over the lower half (mostly floor),
        by phase correlation; none when the peak is weak or the shift too large to be a small error."""
        import cv2

        cfg = self.config
        h = warped.shape[0]
        lo = slice(h // 2, h)
        if valid[lo].mean() < 0.5:
            return (0.0, 0.0)
        if self._hann is None or self._hann.shape != warped[lo].shape:
            self._hann = np.asarray(
                cv2.createHanningWindow(warped[lo].shape[::-1], cv2.CV_32F), dtype=np.float32
            )
        (du, dv), response = cv2.phaseCorrelate(current[lo], warped[lo], self._hann)
        if response < 0.05 or not 0.5 <= math.hypot(du, dv) <= cfg.max_shift:
            return (0.0, 0.0)  # weak, below half a pixel, or too large to be a small error
        return (float(du), float(dv))

    def _visitors(self, view: View) -> FloatArray:
        """The tracker's visitors of ``view`` that its scan does not show to be posts: a track whose
        laser returns (within ``person_radius``) are all runs narrower than ``min_leg`` stands on
        a table's legs, not on a visitor's; a track with no return near it (hidden from the
        laser) is kept."""
        cfg = self.config
        people = np.asarray(view.people, dtype=np.float64).reshape(-1, 2)
        if not len(people):
            return people
        ret = view.endpoints[view.returned]
        if not len(ret):
            return people
        wide = view.endpoints[view.returned & _wide_clusters(view.endpoints, view.returned, cfg.min_leg)]
        near_any = np.isfinite(cKDTree(ret).query(people, distance_upper_bound=cfg.person_radius)[0])
        near_wide = np.zeros(len(people), dtype=bool)
        if len(wide):
            near_wide = np.isfinite(cKDTree(wide).query(people, distance_upper_bound=cfg.person_radius)[0])
        return people[near_wide | ~near_any]

    def _moving_mask(
        self, prev: View, cur: View, azimuth: FloatArray, position: FloatArray
    ) -> NDArray[np.bool_]:
        """Pixels whose azimuth passes within ``body`` of a laser endpoint that moved."""
        cfg = self.config
        reach = cfg.max_distance + 5.0
        moved = []
        for a, b in ((cur, prev), (prev, cur)):
            pa = a.endpoints[a.returned & _wide_clusters(a.endpoints, a.returned, cfg.min_leg)]
            pb = b.endpoints[b.returned]
            pa = pa[np.hypot(pa[:, 0] - position[0], pa[:, 1] - position[1]) < reach]
            if not len(pa):
                continue
            if len(pb):
                d, _ = cKDTree(pb).query(pa, distance_upper_bound=cfg.moving)
                pa = pa[~np.isfinite(d)]
            moved.append(pa)
        bins = np.zeros(self._n_az, dtype=bool)
        pts = np.vstack(moved) if moved else np.zeros((0, 2))
        for x, y in pts:
            dist = math.hypot(x - position[0], y - position[1])
            az = math.atan2(y - position[1], x - position[0])
            half = math.atan2(cfg.body, dist)
            k0 = math.floor((az - half + math.pi) / cfg.azimuth_step)
            k1 = math.ceil((az + half + math.pi) / cfg.azimuth_step)
            bins[np.arange(k0, k1 + 1) % self._n_az] = True
        if not bins.any():
            return np.zeros(azimuth.shape, dtype=bool)
        k = np.round((azimuth + math.pi) / cfg.azimuth_step).astype(np.int64) % self._n_az
        return np.asarray(bins[k])

    def _search(
        self,
        prev: View,
        cur: View,
        inconsistent: NDArray[np.bool_],
        rays: Float32Array,
        pos_c: FloatArray,
        t_model: Float32Array,
        rot_p: FloatArray,
        pos_p: FloatArray,
        shift: tuple[float, float],
        body_prev: NDArray[np.bool_],
    ) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """Depth along each inconsistent pixel's ray that best matches image t-1 (patch NCC)."""
        import cv2

        cfg = self.config
        s = cfg.stride
        sub = np.zeros_like(inconsistent)
        sub[s // 2 :: s, s // 2 :: s] = True
        vv, uu = np.nonzero(inconsistent & sub)
        empty = (np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2), dtype=np.int64))
        if not len(vv):
            return empty
        if len(vv) > cfg.max_pixels:
            keep = np.linspace(0, len(vv) - 1, cfg.max_pixels).astype(np.int64)
            vv, uu = vv[keep], uu[keep]
        d = rays[vv, uu].astype(np.float64)  # (M, 3)
        h = np.hypot(d[:, 0], d[:, 1])
        s_model = t_model[vv, uu] * h
        s_hi = np.minimum(cfg.max_distance, s_model - cfg.in_front)
        ok = (s_hi > cfg.min_distance) & (h > 1e-6)
        vv, uu, d, h, s_hi, s_model = vv[ok], uu[ok], d[ok], h[ok], s_hi[ok], s_model[ok]
        if not len(vv):
            return empty
        # depths uniform in inverse distance from min_distance to s_hi
        f = np.linspace(0.0, 1.0, cfg.depths)
        inv = 1.0 / cfg.min_distance + f[None, :] * (1.0 / s_hi[:, None] - 1.0 / cfg.min_distance)
        dist = 1.0 / inv  # (M, K) horizontal distances
        # the model's own depth last: a match must beat it by ``margin``
        dist = np.hstack([dist, np.minimum(s_model, cfg.max_distance + 50.0)[:, None]])
        pts = pos_c[None, None, :] + d[:, None, :] * (dist / h[:, None])[..., None]  # (M, K, 3)
        uv = self.camera.project(rot_p, pos_p, pts).astype(np.float32)  # (M, K, 2)
        uv += np.array(shift, dtype=np.float32)
        hgt, wid = prev.image.shape
        inside = (uv[..., 0] >= 0) & (uv[..., 0] <= wid - 1) & (uv[..., 1] >= 0) & (uv[..., 1] <= hgt - 1)
        uv[~inside] = -1e4
        offs = self._offsets  # (P, 2)
        here = np.stack([uu, vv], axis=-1).astype(np.float32)[:, None, :] + offs[None, :, :]  # (M, P, 2)
        a = cv2.remap(
            cur.image, here[..., 0], here[..., 1], cv2.INTER_NEAREST, borderMode=cv2.BORDER_REFLECT
        ).astype(np.float32)
        there = uv[:, :, None, :] + offs[None, None, :, :]  # (M, K, P, 2)
        n = len(vv)
        b = cv2.remap(
            prev.image.astype(np.float32),
            there[..., 0].reshape(n, -1),
            there[..., 1].reshape(n, -1),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0.0,
        ).reshape(n, cfg.depths + 1, -1)
        score = patch_ncc(a, np.asarray(b, dtype=np.float32))
        # a candidate on a visitor's body in image t-1 is no match for a point of the world
        on_body = np.zeros(inside.shape, dtype=bool)
        if body_prev.any():
            iu = np.clip(np.round(uv[..., 0]), 0, wid - 1).astype(np.int64)
            iv = np.clip(np.round(uv[..., 1]), 0, hgt - 1).astype(np.int64)
            on_body = body_prev[iv, iu] & inside
        score = np.where(inside & ~on_body, score, -1.0)
        best = np.argmax(score[:, :-1], axis=1)
        rows = np.arange(len(vv))
        top = score[rows, best]
        good = (top >= cfg.match) & (top >= score[:, -1] + cfg.margin)
        # unique: no depth three or more steps away matches nearly as well (stripes, blank walls)
        k = np.arange(cfg.depths)[None, :]
        far = np.abs(k - best[:, None]) >= 3
        second = np.where(far, score[:, :-1], -1.0).max(axis=1)
        good &= top >= second + cfg.unique
        # a best depth at the end of the range is no depth: the match is not bracketed
        good &= (best > 0) & (best < cfg.depths - 1)
        p3 = pts[rows, best][good]
        px = np.stack([uu, vv], axis=-1)[good]
        z = p3[:, 2]
        # triangulation angle: near the epipole the depth is not determined by the images
        ra = p3 - pos_c
        rb = p3 - pos_p
        cosang = np.einsum("ij,ij->i", ra, rb) / (
            np.linalg.norm(ra, axis=1) * np.linalg.norm(rb, axis=1) + 1e-12
        )
        parallax = np.arccos(np.clip(cosang, -1.0, 1.0))
        keep = (z >= cfg.min_height) & (z <= cfg.max_height) & (parallax >= cfg.min_parallax)
        p3, px = p3[keep], px[keep]
        if len(p3):
            laser = cur.endpoints[cur.returned]
            if len(laser):
                dd, _ = cKDTree(laser).query(p3[:, :2], distance_upper_bound=cfg.laser_explains)
                far = ~np.isfinite(dd)
                p3, px = p3[far], px[far]
        return p3[:, :2].copy(), p3[:, 2].copy(), px.astype(np.int64)


def body_mask(
    rays: Float32Array | FloatArray,
    origin: FloatArray,
    people: FloatArray,
    radius: float,
    height: float,
    step: int = 4,
) -> NDArray[np.bool_]:
    """The pixels ``(H, W)`` whose rays (world directions ``(H, W, 3)`` from ``origin``) meet an
    upright cylinder of ``radius`` and ``height`` standing on the floor at one of ``people``
    ``(N, 2)`` before the floor: a visitor's body. Computed on every ``step``-th pixel, each
    answer held for its ``step`` x ``step`` block."""
    h, w = rays.shape[:2]
    if not len(people):
        return np.zeros((h, w), dtype=bool)
    half = step // 2
    sub = np.asarray(rays[half::step, half::step], dtype=np.float64)
    dx, dy, dz = sub[..., 0], sub[..., 1], sub[..., 2]
    a = dx * dx + dy * dy
    hit = np.zeros(sub.shape[:2], dtype=bool)
    ox0, oy0, oz = (float(v) for v in origin[:3])
    for px, py in np.asarray(people, dtype=np.float64).reshape(-1, 2):
        ox, oy = ox0 - px, oy0 - py
        b = dx * ox + dy * oy  # half the quadratic's b
        c = ox * ox + oy * oy - radius * radius
        disc = b * b - a * c
        ok = (disc > 0.0) & (a > 1e-12)
        root = np.sqrt(np.maximum(disc, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_out = (-b + root) / a
            t_in = np.maximum((-b - root) / a, 0.0)
        z_in, z_out = oz + t_in * dz, oz + t_out * dz
        hit |= ok & (t_out > 0.0) & (z_in >= 0.0) & (np.minimum(z_in, z_out) <= height)
    full = np.repeat(np.repeat(hit, step, axis=0), step, axis=1)
    out = np.zeros((h, w), dtype=bool)
    rows, cols = min(h, full.shape[0]), min(w, full.shape[1])
    out[:rows, :cols] = full[:rows, :cols]
    if rows < h:
        out[rows:] = out[rows - 1]
    if cols < w:
        out[:, cols:] = out[:, cols - 1 : cols]
    return out


def _in_arc(azimuths: FloatArray, lo: float, hi: float) -> NDArray[np.bool_]:
    """Which ``azimuths`` lie on the arc from ``lo`` to ``hi`` (counter-clockwise, radians)."""
    return np.asarray(np.mod(azimuths - lo, 2 * math.pi) <= (hi - lo))


def _wide_clusters(endpoints: FloatArray, returned: NDArray[np.bool_], width: float) -> NDArray[np.bool_]:
    """Which endpoints belong to a run of consecutive returns (each within 0.1 m of the next) at
    least ``width`` from end to end: legs, bodies, walls, but not a thin post."""
    n = len(endpoints)
    step = np.hypot(*np.diff(endpoints, axis=0).T)
    joined = returned[:-1] & returned[1:] & (step < 0.1)
    start = np.r_[0, np.flatnonzero(~joined) + 1]
    end = np.r_[np.flatnonzero(~joined), n - 1]
    extent = np.hypot(*(endpoints[end] - endpoints[start]).T)
    out = np.zeros(n, dtype=bool)
    for s0, e0, ext in zip(start, end, extent, strict=True):
        if ext >= width:
            out[s0 : e0 + 1] = True
    return out
