"""Record the image pairs the forward camera's detector uses on FHW's short tour, and replay them
through the detector and the vision map with other settings (docs/results/vision.md).

A tour rendered with the camera takes minutes; a replay of its pairs seconds. The recording keeps,
per pair, the two views (image, the estimated pose, the laser's endpoints), the estimate's
covariance, the people tracker's tracks at each image (what the robot knew) and, for the figures
only, the true pose and the true visitors. The replay places the pairs by the recorded estimates,
masks the tracker's visitors (or none), and scores the map as ``tourbot bench vision`` does.

    PYTHONPATH=src python scripts/vision_pairs.py record 3 peak pairs-3-peak.pkl
    PYTHONPATH=src python scripts/vision_pairs.py replay --people tracker pairs-*-peak.pkl

A drive-by (no tour, no crowd, the true poses: a diagnostic of the detector alone) drives straight
from a pose at a speed for some seconds and records the views; ``drive-score`` replays them and
gives each named obstacle's outline found, per side:

    PYTHONPATH=src python scripts/vision_pairs.py drive -2.3,9.0,1.5708 0.3 6.5 glass.pkl
    PYTHONPATH=src python scripts/vision_pairs.py drive-score glass.pkl --obstacles glass-case-lekythos
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np


def record(seed: int, crowd: str, max_time: float, out: Path) -> None:
    import cv2

    from tourbot.app.demo import start_pose_for
    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.bench import vision as bench
    from tourbot.navigation.navigator import NavigationConfig
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site
    from tourbot.snapshot import NavMode

    cv2.setNumThreads(1)
    site = load_site(site_path("fhw"))
    nav = NavigationConfig(hand_drawn=False, dwell_scale=bench.DWELL_SCALE)
    settings = SimulationSettings(crowd=crowd, seed=seed, vision=True, navigation=nav)
    robot = simulated_runtime(site, settings, start=start_pose_for(site, bench.TOUR), record=False)
    rt, sim = robot.runtime, robot.simulator
    est: Any = next(e for e in rt.estimators if e.name == "vision")
    people: Any = next(e for e in rt.estimators if e.name == "people")
    info: dict[int, dict[str, Any]] = {}
    on_image = est.on_image

    def image_hook(image: Any, belief: Any = None) -> Any:
        tracks = [(t.position, t.confirmed, 0.0) for t in people._tracks]
        info[id(image.pixels)] = {
            "truth": np.array(sim.robot.pose),  # metrics only
            "people": sim.people_positions().copy(),  # metrics only
            "tracks": tracks,
            "time": sim.time,
        }
        return on_image(image, belief)

    pairs: list[tuple[Any, ...]] = []
    add_pair = est.add_pair

    def pair_hook(prev: Any, cur: Any, cov: Any) -> Any:
        pairs.append((prev, cur, info[id(prev.image)], info[id(cur.image)], np.array(cov)))
        return add_pair(prev, cur, cov)

    est.on_image, est.add_pair = image_hook, pair_hook
    rt.start_tour(bench.TOUR)
    rt.run(max_time=max_time, until=lambda s: s.navigation.mode in (NavMode.FINISHED, NavMode.FAILED))
    with out.open("wb") as fh:
        pickle.dump(pairs, fh)
    print(f"{out}: {len(pairs)} pairs, collisions {sim.collisions}")


def _visitors(info: dict[str, Any], mode: str) -> np.ndarray:
    if mode == "none":
        return np.zeros((0, 2))
    return np.asarray([p for p, confirmed, _ in info["tracks"] if confirmed], dtype=np.float64).reshape(-1, 2)


def replay(files: list[Path], mode: str, overrides: dict[str, Any]) -> list[dict[str, Any]]:
    import cv2

    from tourbot.bench import vision as bench
    from tourbot.robot import DiffDriveConfig
    from tourbot.runtime.vision import VisionEstimatorConfig, VisionObstacleEstimator
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site
    from tourbot.vision.camera import ForwardCamera
    from tourbot.vision.detector import View, VisionConfig

    cv2.setNumThreads(1)
    site = load_site(site_path("fhw"))
    robot = DiffDriveConfig()
    config = VisionEstimatorConfig(detector=replace(VisionConfig(), **overrides))
    out = []
    for f in files:
        with f.open("rb") as fh:
            pairs = pickle.load(fh)  # our own recordings
        est = VisionObstacleEstimator(site.grid, ForwardCamera(), config)
        path = []
        for prev, cur, ip, ic, cov in pairs:
            a = View(prev.image, prev.pose, prev.endpoints, prev.returned, _visitors(ip, mode))
            b = View(cur.image, cur.pose, cur.endpoints, cur.returned, _visitors(ic, mode))
            est.add_pair(a, b, cov)
            path += [ip["truth"][:2], ic["truth"][:2]]
        vm = est.map
        near_real, _ = bench._truth_masks(site, vm.frame)
        false = int((vm.occupied() & ~near_real).sum())
        seen = int((vm.floor_seen & ~near_real).sum())
        outline = bench._outline_found(site, np.asarray(path), vm.obstacle_points(), robot.laser_height)
        row = {
            "file": f.name,
            "pairs": len(pairs),
            "false": false,
            "seen": seen,
            "share": false / max(seen, 1),
        }
        row["outline"] = outline
        out.append(row)
        print(json.dumps(row), flush=True)
    return out


def drive(start: tuple[float, ...], speed: float, seconds: float, out: Path) -> None:
    import cv2

    from tourbot.records import Image, Scan
    from tourbot.sim.camera import ForwardCameraSim
    from tourbot.sim.simulator import SimConfig, Simulator
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site
    from tourbot.vision.model import scan_endpoints

    cv2.setNumThreads(1)
    site = load_site(site_path("fhw"))
    cam = ForwardCameraSim(site, seed=0)
    sim = Simulator(site, SimConfig(dynamic_objects=False), seed=0, start=start, cameras=[cam])
    views: list[tuple[Any, ...]] = []
    scan = None
    while sim.time < seconds:
        sim.command(speed, 0.0)
        for r in sim.poll() or []:
            if isinstance(r, Scan):
                scan = r
            elif isinstance(r, Image) and scan is not None:
                pose = np.array(sim.robot.pose)  # the truth: a diagnostic of the detector alone
                ep, ok = scan_endpoints(scan, pose)
                views.append((r.pixels, pose, ep, ok))
    with out.open("wb") as fh:
        pickle.dump(views, fh)
    print(f"{out}: {len(views)} views, collisions {sim.collisions}")


def drive_score(files: list[Path], names: list[str], overrides: dict[str, Any]) -> None:
    import cv2
    from scipy.spatial import cKDTree

    from tourbot.bench import vision as bench
    from tourbot.runtime.vision import VisionEstimatorConfig, VisionObstacleEstimator
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site, rasterize_polygons
    from tourbot.vision.camera import ForwardCamera
    from tourbot.vision.detector import View, VisionConfig

    cv2.setNumThreads(1)
    site = load_site(site_path("fhw"))
    cfg = VisionEstimatorConfig(detector=replace(VisionConfig(), **overrides))
    for f in files:
        with f.open("rb") as fh:
            views = [View(*v) for v in pickle.load(fh)]  # our own recordings
        est = VisionObstacleEstimator(site.grid, ForwardCamera(), cfg)
        prev = views[0]
        for cur in views[1:]:
            if np.hypot(*(cur.pose[:2] - prev.pose[:2])) >= cfg.min_baseline:
                est.add_pair(prev, cur, np.zeros((3, 3)))
                prev = cur
        pts = est.map.obstacle_points()
        for obs in (o for o in site.invisible_obstacles if o.name in names):
            xy = site.grid.cell_to_world(
                np.argwhere(rasterize_polygons(site.grid, [obs.outline], outline_only=True))
            )
            found = (
                (cKDTree(pts).query(xy)[0] <= bench.TARGET_WITHIN + 1e-9)
                if len(pts)
                else np.zeros(len(xy), bool)
            )
            o = np.asarray(obs.outline)
            c, half = o.mean(axis=0), np.ptp(o, axis=0) / 2
            d = (xy - c) / half
            side = np.where(
                np.abs(d[:, 0]) > np.abs(d[:, 1]),
                np.where(d[:, 0] > 0, "E", "W"),
                np.where(d[:, 1] > 0, "N", "S"),
            )
            per = {k: f"{int(found[side == k].sum())}/{int((side == k).sum())}" for k in "NESW"}
            row = {"file": f.name, "obstacle": obs.name, "found": float(found.mean()), "sides": per}
            print(json.dumps(row | {"pairs": est.pairs}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("seed", type=int)
    rec.add_argument("crowd")
    rec.add_argument("out", type=Path)
    rec.add_argument("--max-time", type=float, default=70.0)
    rep = sub.add_parser("replay")
    rep.add_argument("files", type=Path, nargs="+")
    rep.add_argument("--people", choices=["tracker", "none"], default="tracker")
    rep.add_argument("--set", default="{}", help="VisionConfig fields as JSON")
    drv = sub.add_parser("drive")
    drv.add_argument("start", help="x,y,theta")
    drv.add_argument("speed", type=float)
    drv.add_argument("seconds", type=float)
    drv.add_argument("out", type=Path)
    dsc = sub.add_parser("drive-score")
    dsc.add_argument("files", type=Path, nargs="+")
    dsc.add_argument("--obstacles", default="glass-case-lekythos,table-guestbook")
    dsc.add_argument("--set", default="{}", help="VisionConfig fields as JSON")
    args = ap.parse_args()
    if args.cmd == "record":
        record(args.seed, args.crowd, args.max_time, args.out)
        return
    if args.cmd == "drive":
        drive(tuple(float(v) for v in args.start.split(",")), args.speed, args.seconds, args.out)
        return
    if args.cmd == "drive-score":
        drive_score(args.files, args.obstacles.split(","), json.loads(args.set))
        return
    rows = replay(args.files, args.people, json.loads(args.set))
    share = [r["share"] for r in rows]
    print(json.dumps({"people": args.people, "set": args.set, "share_mean": float(np.mean(share))}))


if __name__ == "__main__":
    sys.exit(main())
