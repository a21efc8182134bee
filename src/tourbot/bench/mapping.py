"""``tourbot bench mapping``: grid and line-feature SLAM on real logs, and people filtering on FHW.

For each log: the mean relative translational and rotational error between consecutive scan poses
against the corrected reference (Kummerle et al. 2009 style; raw odometry given for comparison),
how well the map agrees with the reference map built from the corrected poses, the time per scan
and the real-time factor, for the grid scan matcher, graph SLAM, the line-feature EM mapper (Sec. 2.2)
and the KISS-ICP peer. Then, on FHW with the peak crowd overlay: the occupied cells caused by
people in maps built with and without people filtering (Burgard et al. Fig. 10), with a picture;
and (``--people-sim``) the same on a simulated 10 Hz tour in the peak crowd, where the laser knows
which beams hit a visitor.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer
from numpy.typing import NDArray
from rich.console import Console

from tourbot.maps.grid import OccupancyGrid
from tourbot.metrics.closures import ClosureAudit, audit_closures
from tourbot.metrics.maps import map_agreement, occupied_distance, register_map
from tourbot.records import RobotLog, Scan

if TYPE_CHECKING:
    from tourbot.mapping.people_filter import PeopleFilterParams, PeopleMappingConfig

__all__ = [
    "clean_map",
    "hit_scans",
    "map_agreement",
    "people_cells",
    "register",
    "simulated_crowd_log",
]

LOGS = ("intel", "aces", "freiburg-079", "fhw")


def people_cells(
    grid: OccupancyGrid, static: OccupancyGrid, person_cells: NDArray[np.bool_], tolerance: float = 0.05
) -> dict[str, int]:
    """Occupied cells of ``grid`` caused by people, and the static map's occupied cells it keeps.

    All three on the same cells. ``person_cells`` marks the cells where a beam that really hit a
    visitor ended (the crowd overlay's ground truth); those of them that ``grid`` has occupied and
    that are farther than ``tolerance`` from the static map's occupied cells were caused by people.
    A static occupied cell is kept when ``grid`` has it occupied too.
    """
    far = occupied_distance(static) > tolerance
    occupied = grid.occupied()
    return {
        "people": int(np.sum(occupied & person_cells & far)),
        "static_kept": int(np.sum(occupied & static.occupied())),
        "static": int(np.sum(static.occupied())),
    }


def _person_cells(log: RobotLog, corrupted: NDArray[np.bool_], like: OccupancyGrid) -> NDArray[np.float64]:
    """For each cell of ``like``, the shortest range at which a beam that hit a visitor ended in
    it (at the reference poses); infinite where none did."""
    from tourbot.mapping.people_filter import beam_endpoints

    nearest = np.full(like.prob.shape, np.inf)
    for scan, pose, bad in zip(log.scans, log.reference_poses, corrupted, strict=True):
        pts, hit = beam_endpoints(scan, pose)
        cells = like.world_to_cell(pts[hit & bad])
        ranges = np.asarray(scan.ranges, dtype=np.float64)[hit & bad]
        inside = like.inside(cells)
        np.minimum.at(nearest, (cells[inside, 0], cells[inside, 1]), ranges[inside])
    return nearest


def hit_scans(
    log: RobotLog, left_out: NDArray[np.bool_], like: OccupancyGrid, radius: int = 0
) -> tuple[NDArray[np.int32], NDArray[np.float64]]:
    """For each cell of ``like``: how many distinct scans of ``log`` (at its reference poses) had a
    returned beam, not in ``left_out`` ``(S, B)``, ending within ``radius`` cells (the square
    around it), and the farthest distance (m) between the laser positions of the first such scan
    and a later one. A confirmation rule of mappers for dynamic scenes maps a cell only when at
    least K scans hit it, or hit it from positions some distance apart."""
    from tourbot.geometry import compose
    from tourbot.mapping.people_filter import beam_endpoints

    count = np.zeros(like.prob.shape, np.int32)
    first = np.full((*like.prob.shape, 2), np.nan)
    baseline = np.zeros(like.prob.shape)
    k = np.arange(-radius, radius + 1)
    around = np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)
    for scan, pose, out in zip(log.scans, log.reference_poses, left_out, strict=True):
        pts, hit = beam_endpoints(scan, pose)
        ends = like.world_to_cell(pts[hit & ~out])
        cells = (ends[:, None, :] + around[None, :, :]).reshape(-1, 2)
        cells = np.unique(cells[like.inside(cells)], axis=0)  # each scan counts once per cell
        rows, cols = cells[:, 0], cells[:, 1]
        count[rows, cols] += 1
        laser = compose(np.asarray(pose, dtype=np.float64), scan.geometry.offset)[:2]
        seen = first[rows, cols]
        seen[np.isnan(seen[:, 0])] = laser
        first[rows, cols] = seen
        gap = np.hypot(seen[:, 0] - laser[0], seen[:, 1] - laser[1])
        baseline[rows, cols] = np.maximum(baseline[rows, cols], gap)
    return count, baseline


CONFIRM_RULES = ((0, 2), (0, 3), (1, 2), (2, 2), (3, 2))  # (radius in cells, scans)


def _confirmation(
    log: RobotLog,
    left_out: NDArray[np.bool_],
    like: OccupancyGrid,
    people: NDArray[np.bool_],
    static: NDArray[np.bool_],
) -> dict[str, float]:
    """What confirmation rules would leave of a map's ``people`` and ``static`` occupied cells:
    the cells hit in one scan only, and for each rule (at least K scans within r cells; two scans
    at least 1 m apart) the people cells left and the static cells kept."""
    out: dict[str, float] = {}
    for radius, scans in CONFIRM_RULES:
        count, baseline = hit_scans(log, left_out, like, radius)
        if radius == 0 and scans == 2:
            for name, mask in (("people", people), ("static", static)):
                hist = np.bincount(count[mask], minlength=5)
                for k in range(1, 5):
                    out[f"confirm_{name}_hit_in_{k}_scans"] = int(hist[k])
                out[f"confirm_{name}_hit_in_5+_scans"] = int(hist[5:].sum())
                out[f"confirm_{name}_baseline_1m"] = int(np.sum(mask & (baseline >= 1.0)))
        ok = count >= scans
        out[f"confirm_r{radius}_k{scans}_people"] = int(np.sum(people & ok))
        out[f"confirm_r{radius}_k{scans}_static"] = int(np.sum(static & ok))
    return out


RANGE_BANDS = ((0.0, 4.0), (4.0, 8.0), (8.0, np.inf))  # the leg detector resolves legs to ~4 m, sees to 8


def _by_range(grid: OccupancyGrid, clean: OccupancyGrid, nearest: NDArray[np.float64]) -> list[int]:
    """People cells of ``grid`` split by the range at which a visitor was seen there."""
    cells = grid.occupied() & np.isfinite(nearest) & (occupied_distance(clean) > 0.05)
    return [int(np.sum(cells & (nearest >= lo) & (nearest < hi))) for lo, hi in RANGE_BANDS]


@dataclass
class _Run:
    poses: NDArray[np.float64]
    grid: OccupancyGrid
    seconds: float  # wall clock
    cpu_seconds: float  # this process's CPU time (the machine is shared: less noisy)
    closures: list[tuple[int, int, tuple[float, float, float]]] = field(default_factory=list)
    rejected: int = 0
    proposed: int = 0  # matches proposed (graph SLAM): accepted, rejected, contradicted or alone
    contradicted: int = 0


def _read(name: str, max_scans: int | None) -> RobotLog:
    """A corrected log with its odometry rebuilt from the increments (the reader's default: the
    stream as stored is re-anchored to the reference at every scan)."""
    from tourbot.data import find_data
    from tourbot.io.carmen import read_carmen

    log = read_carmen(find_data(f"carmen/{name}-corrected.log.gz"))
    if max_scans is not None:
        log.scans = log.scans[:max_scans]
    return log


def _slam(log: RobotLog, start: NDArray[np.float64], loop_closure: bool = False) -> _Run:
    """Incremental scan matching over ``log`` from the pose ``start`` (it fixes the map's frame);
    with ``loop_closure``, graph SLAM on top of it."""
    from tourbot.mapping.graph_slam import GraphSlam
    from tourbot.mapping.incremental import IncrementalMapper

    warm = IncrementalMapper(start=start)
    for scan in log.scans[:3]:  # the numba kernels load before the clock starts
        warm.add_scan(scan)
    if not loop_closure:
        mapper = IncrementalMapper(start=start)
        t0, c0 = time.perf_counter(), time.process_time()
        for scan in log.scans:
            mapper.add_scan(scan)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        return _Run(np.asarray(mapper.poses), mapper.grid(), seconds, cpu)
    slam = GraphSlam(start=start)
    t0, c0 = time.perf_counter(), time.process_time()
    for scan in log.scans:
        slam.add_scan(scan)
    poses = slam.finish()
    grid = slam.grid()  # drawing the final map counts: it is part of the run
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    closures = [(c.anchor, c.node, c.delta) for c in slam.closures]
    return _Run(poses, grid, seconds, cpu, closures, slam.rejected, slam.proposed, slam.contradicted)


def _features(log: RobotLog, start: NDArray[np.float64]) -> _Run:
    """Feature-based mapping (Burgard et al. Sec. 2.2: lines and corners, EM with the RTS smoother)
    over ``log`` from ``start``; its map is the occupancy grid drawn from the line map."""
    from tourbot.mapping.features import FeatureMapper
    from tourbot.site.model import segment_walls, walls_grid

    t0, c0 = time.perf_counter(), time.process_time()
    result = FeatureMapper().run(log.scans, start=start)
    segments = result.segments()
    grid = walls_grid(segment_walls(segments)) if len(segments) else _map_at(log, result.poses, 0.0).grid
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    closures = [(c.seen, c.scan, c.delta) for c in result.closures]
    return _Run(result.poses, grid, seconds, cpu, closures)


def _map_at(log: RobotLog, poses: NDArray[np.float64], seconds: float) -> _Run:
    """The map of ``log``'s scans at ``poses`` (a peer's path), as a run of ``seconds``."""
    from tourbot.mapping.incremental import IncrementalMapper

    mapper = IncrementalMapper(start=poses[0])
    for scan, pose in zip(log.scans, poses, strict=True):
        mapper.integrate(scan, pose, into="map")
    return _Run(poses, mapper.grid(), seconds, seconds)


def _audit(log: RobotLog, run: _Run | None, ref: NDArray[np.float64]) -> ClosureAudit:
    """The run's accepted closures against the reference, and against the scans where the two
    disagree (:mod:`tourbot.metrics.closures`)."""
    from tourbot.geometry import transform_points
    from tourbot.mapping.mounts import scan_points

    closures = run.closures if run is not None and run.closures else []
    if not closures:
        return ClosureAudit(0, 0, 0)
    used = {k for i, j, _ in closures for k in (i, j)}
    points = [
        transform_points(s.geometry.offset, scan_points(s)) if k in used else np.zeros((0, 2))
        for k, s in enumerate(log.scans)
    ]
    return audit_closures(closures, ref, points)


# whole-log relation error (m) published for these logs: Kummerle et al. 2009 (graph mapping) and
# Hess et al. 2016 (Cartographer)
ANCHORS = {
    "intel": {"kummerle_graph": 0.031, "cartographer": 0.023},
    "aces": {"kummerle_graph": 0.044, "cartographer": 0.038},
    "freiburg-079": {"kummerle_graph": 0.056, "cartographer": 0.045},
}


def register(bench: typer.Typer) -> None:
    @bench.command("mapping")
    def mapping(
        logs: Annotated[
            str,
            typer.Option(help="Comma-separated logs of ../shared/data/carmen (without -corrected.log.gz)."),
        ] = ",".join(LOGS),
        people: Annotated[
            bool, typer.Option(help="Also measure people filtering on FHW with the peak crowd.")
        ] = True,
        max_scans: Annotated[
            int | None, typer.Option(help="Only the first N scans of each log (quick runs).")
        ] = None,
        seed: Annotated[int, typer.Option(help="Seed of the crowd and the people tracker.")] = 0,
        people_sim: Annotated[
            bool,
            typer.Option(help="Also measure people filtering on a simulated tour in the peak crowd (10 Hz)."),
        ] = False,
        sim_seconds: Annotated[
            float, typer.Option(help="Simulated seconds of each --people-sim run.")
        ] = 180.0,
        sim_seeds: Annotated[int, typer.Option(help="Number of --people-sim runs (seeds 0, 1, ...).")] = 1,
        output: Annotated[Path | None, typer.Option("-o", "--output", help="JSON file to write.")] = None,
        picture: Annotated[
            Path, typer.Option(help="Picture of the maps with and without people filtering.")
        ] = Path("bench-results/mapping-people.png"),
        people_modes: Annotated[
            str,
            typer.Option(
                help="People filter modes to measure on FHW, comma-separated (checked, paper); "
                "the first is drawn and used for scan matching."
            ),
        ] = "checked,paper",
        kiss: Annotated[
            bool, typer.Option("--kiss/--no-kiss", help="Also run the KISS-ICP peer (pip install kiss-icp).")
        ] = True,
        features: Annotated[
            bool,
            typer.Option(
                "--features/--no-features",
                help="Also run feature-based mapping (line features, EM with the RTS smoother, Sec. 2.2).",
            ),
        ] = True,
        grid_slam: Annotated[
            bool,
            typer.Option("--grid/--no-grid", help="Run the grid scan matcher and graph SLAM (Sec. 2.1)."),
        ] = True,
    ) -> None:
        """Relation errors, aligned error, map agreement and speed of SLAM on real logs (rebuilt odometry)."""
        from tourbot.bench._report import BenchReport
        from tourbot.maps.reference import build_reference_map
        from tourbot.metrics.relative import aligned_trajectory_error, relation_error, sample_pairs

        console = Console()
        report = BenchReport(
            "mapping",
            ["log", "method", "scans", "sep trans (m)", "sep rot (deg)", "revisit trans (m)",
             "revisit rot (deg)", "consec trans (m)", "consec rot (deg)", "ATE (m)", "precision",
             "recall", "registered precision", "registered recall", "x real time",
             "x real time (cpu)", "closures", "false closures", "false, the scans side with the closure"],
        )  # fmt: skip
        for name in [n.strip() for n in logs.split(",") if n.strip()]:
            console.print(f"mapping {name} ...")
            log_obj = _read(name, max_scans)
            ref = log_obj.reference_poses
            pairs = sample_pairs(ref)
            reference_map = build_reference_map(log_obj)
            duration = float(log_obj.times[-1] - log_obj.times[0])
            # the reference's first pose puts the map in the reference map's frame, so that the
            # maps can be compared (`tourbot slam` starts at the first odometry pose instead)
            runs: list[tuple[str, NDArray[np.float64], _Run | None, float, float]] = [
                ("odometry (rebuilt)", log_obj.odom_poses, None, float("nan"), float("nan"))
            ]
            for method, closing in (("front end", False), ("graph SLAM", True)) if grid_slam else ():
                done = _slam(log_obj, ref[0], loop_closure=closing)
                runs.append((method, done.poses, done, duration / done.seconds, duration / done.cpu_seconds))
            if features:
                done = _features(log_obj, ref[0])
                runs.append(
                    (
                        "line features (EM)",
                        done.poses,
                        done,
                        duration / done.seconds,
                        duration / done.cpu_seconds,
                    )
                )
            if kiss:
                from tourbot.bench.peers.kiss_icp_adapter import kiss_icp_path

                t0, c0 = time.perf_counter(), time.process_time()
                path = kiss_icp_path(log_obj.scans, ref[0])
                seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
                peer = _map_at(log_obj, path, seconds)
                runs.append(("KISS-ICP (peer)", path, peer, duration / seconds, duration / cpu))
            for method, poses, run, speed, cpu_speed in runs:
                audit = _audit(log_obj, run, ref)
                sep = relation_error(poses, ref, pairs["separation"])
                rev = relation_error(poses, ref, pairs["revisit"])
                con = relation_error(poses, ref, pairs["consecutive"])
                agree = map_agreement(run.grid, reference_map) if run is not None else {}
                moved = (
                    map_agreement(run.grid, reference_map, transform=register_map(run.grid, reference_map))
                    if run is not None
                    else {}
                )
                report.add(
                    **{
                        "log": name,
                        "method": method,
                        "scans": len(log_obj),
                        "sep trans (m)": sep.trans_mean,
                        "sep rot (deg)": float(np.degrees(sep.rot_mean)),
                        "revisit trans (m)": rev.trans_mean,
                        "revisit rot (deg)": float(np.degrees(rev.rot_mean)),
                        "consec trans (m)": con.trans_mean,
                        "consec rot (deg)": float(np.degrees(con.rot_mean)),
                        "ATE (m)": aligned_trajectory_error(poses, ref).rmse,
                        "precision": agree.get("precision", float("nan")),
                        "recall": agree.get("recall", float("nan")),
                        "registered precision": moved.get("precision", float("nan")),
                        "registered recall": moved.get("recall", float("nan")),
                        "x real time": speed,
                        "x real time (cpu)": cpu_speed,
                        "closures": audit.accepted,
                        "false closures": audit.off_reference,
                        "false, the scans side with the closure": audit.scans_side_with_closure,
                        "rejected closures": run.rejected if run is not None else 0,
                        "contradicted closures": run.contradicted if run is not None else 0,
                        "proposed closures": run.proposed if run is not None else 0,
                        "separation pairs": sep.pairs,
                        "revisit pairs": rev.pairs,
                        **{f"anchor {k}": v for k, v in ANCHORS.get(name, {}).items()},
                    }
                )
        report.notes.append(
            "every run from the odometry rebuilt from its increments (the logs' stream is re-anchored "
            "to the reference at every scan); relation error (Kummerle et al. 2009): mean over pose "
            "pairs drawn from the reference path (seed 0): 'sep' 2000 draws 1-50 m apart along the "
            "path, 'revisit' up to 2000 pairs within 1 m of each other after >= 10 m of travel, "
            "'consec' consecutive scans; ATE: RMS position error after SE(2) alignment; "
            "precision/recall: occupied cells within 10 cm of those of the reference map (built "
            "from the corrected poses), as drawn (the map's frame fixed by the reference's first "
            "pose) and registered (after the rigid motion that lays the map onto the reference's, "
            "trimmed ICP: a map is defined up to one); false closures: accepted closures off the "
            "reference by > 0.3 m or 3 deg; of those, 'the scans side with the closure' when the "
            "two scans overlap (returns within 5 cm) by more than 0.02 more at the closure's "
            "relative pose than at the reference's (the reference contradicted there). Targets: "
            "whole-log relation error below Cartographer's (0.023 / "
            "0.038 / 0.045 m on Intel / ACES / FR079), precision and recall >= 0.90, ATE <= 5 cm "
            "on Intel, >= 20x real time, no false closure. Line features (EM): Burgard et al. Sec. "
            "2.2, its map the occupancy grid drawn from the line map (walls only, so its recall "
            "counts the clutter it leaves out), its closures the corner hypotheses that won. "
            "KISS-ICP: its prediction is the "
            "odometry increment, no loop closure. x real time: log duration over wall-clock time of "
            "the run (cpu: over this process's CPU time; the machine is shared)."
        )
        if people:
            modes = [m.strip() for m in people_modes.split(",") if m.strip()]
            report.meta["people_filter"] = _people_experiment(seed, max_scans, picture, console, modes)
        if people_sim:
            sim_picture = picture.with_name(picture.stem + "-sim" + picture.suffix)
            report.meta["people_filter_sim"] = _people_sim_experiment(
                sim_seeds,
                sim_seconds,
                sim_picture,
                console,
                [m.strip() for m in people_modes.split(",") if m.strip()],
            )
        report.finish(output, console)


def _config(params: PeopleFilterParams | None) -> PeopleMappingConfig:
    """People-filtered mapping with the filter ``params`` (the default one for None)."""
    from tourbot.mapping.people_filter import PeopleFilterParams, PeopleMappingConfig

    return PeopleMappingConfig(filter=params or PeopleFilterParams())


def _known_pose_maps(
    log: RobotLog, seed: int, params: PeopleFilterParams | None = None
) -> tuple[OccupancyGrid, OccupancyGrid, NDArray[np.bool_]]:
    """Maps of ``log`` at its reference poses, without and with people filtering; the beams the
    filter left out ``(S, B)``."""
    from tourbot.mapping.incremental import IncrementalMapper
    from tourbot.mapping.people_filter import PeopleFilteredMapper

    ref = log.reference_poses
    plain = IncrementalMapper(start=ref[0])
    filtered = PeopleFilteredMapper.create(_config(params), start=ref[0], seed=seed)
    for scan, pose in zip(log.scans, ref, strict=True):
        plain.integrate(scan, pose)
        filtered.add_scan(scan, pose=pose)
    filtered.finish()
    return plain.grid(), filtered.grid(), np.asarray(filtered.left_out, dtype=bool)


def _align_to(grid: OccupancyGrid, like: OccupancyGrid) -> OccupancyGrid:
    """``grid`` resampled onto ``like``'s cells (same resolution, origins on the same lattice)."""
    res = like.resolution
    dr = round((like.origin[1] - grid.origin[1]) / res)
    dc = round((like.origin[0] - grid.origin[0]) / res)
    out = np.full(like.prob.shape, -1.0, np.float32)
    rows, cols = like.prob.shape
    r0, c0 = max(dr, 0), max(dc, 0)
    r1, c1 = min(dr + rows, grid.prob.shape[0]), min(dc + cols, grid.prob.shape[1])
    if r1 > r0 and c1 > c0:
        out[r0 - dr : r1 - dr, c0 - dc : c1 - dc] = grid.prob[r0:r1, c0:c1]
    return OccupancyGrid(out, res, like.origin, like.occupied_thresh, like.free_thresh)


@dataclass
class _PeopleMaps:
    """The figures of one people-filtering case and the maps they come from."""

    figures: dict[str, float]
    plain: OccupancyGrid
    filtered: OccupancyGrid
    truth: NDArray[np.bool_]  # cells where a beam that hit a visitor ended


def _people_maps(
    crowded: RobotLog,
    corrupted: NDArray[np.bool_],
    clean: OccupancyGrid,
    seed: int,
    params: PeopleFilterParams | None = None,
) -> _PeopleMaps:
    """Maps of the ``crowded`` log at its reference poses without and with people filtering, scored
    against the ``clean`` map (the same poses without people) with the beams known to have hit a
    visitor (``corrupted`` ``(S, B)``): people cells removed, static cells kept (Fig. 10)."""
    plain, filtered, left_out = _known_pose_maps(crowded, seed, params)
    plain, filtered = _align_to(plain, clean), _align_to(filtered, clean)
    nearest = _person_cells(crowded, corrupted, clean)
    truth = np.isfinite(nearest)
    # the endpoints alone (the paper's Fig. 10 draws them): cells far from the walls holding the
    # endpoint of a visitor's beam, before and after the filter left its beams out
    far = occupied_distance(clean) > 0.05
    kept = np.isfinite(_person_cells(crowded, corrupted & ~left_out, clean))
    returned = np.stack([_returned(s) for s in crowded.scans])
    others = returned & ~corrupted
    before = people_cells(plain, clean, truth)
    after = people_cells(filtered, clean, truth)
    bands_before, bands_after = _by_range(plain, clean, nearest), _by_range(filtered, clean, nearest)
    result: dict[str, float] = {
        "corrupted_beams": float(np.mean(corrupted)),
        "corrupted_beam_count": int(np.sum(corrupted)),
        "beams_removed": int(left_out.sum()),
        # beams: of those that hit a visitor, the share left out; of the others, the share kept
        "person_beams_left_out": float(np.sum(left_out & corrupted)) / max(int(np.sum(corrupted)), 1),
        "other_beams_kept": float(np.sum(others & ~left_out)) / max(int(np.sum(others)), 1),
        "endpoint_cells_unfiltered": int(np.sum(truth & far)),
        "endpoint_cells_filtered": int(np.sum(kept & far)),
        "people_cells_unfiltered": before["people"],
        "people_cells_filtered": after["people"],
        "people_cells_removed": 1.0 - after["people"] / max(before["people"], 1),
        "static_cells": after["static"],
        "static_kept_unfiltered": before["static_kept"] / max(before["static"], 1),
        "static_kept_filtered": after["static_kept"] / max(after["static"], 1),
        # the target: of the static cells the crowded map still has, how many filtering keeps
        "static_kept": after["static_kept"] / max(before["static_kept"], 1),
        "static_kept_unfiltered_count": before["static_kept"],
    }
    far_people = filtered.occupied() & truth & far
    static_kept = filtered.occupied() & clean.occupied() & plain.occupied()
    result.update(_confirmation(crowded, left_out, clean, far_people, static_kept))
    ranges = np.stack([np.asarray(s.ranges, dtype=np.float64) for s in crowded.scans])
    for (lo, hi), n0, n1 in zip(RANGE_BANDS, bands_before, bands_after, strict=True):
        band = f"{lo:g}-{hi:g}m"
        result[f"people_cells_unfiltered_{band}"] = n0
        result[f"people_cells_filtered_{band}"] = n1
        seen = corrupted & (ranges >= lo) & (ranges < hi)
        result[f"person_beams_{band}"] = int(seen.sum())
        result[f"person_beams_left_out_{band}"] = float(np.sum(seen & left_out)) / max(int(seen.sum()), 1)
    return _PeopleMaps(result, plain, filtered, truth)


def _returned(scan: Scan) -> NDArray[np.bool_]:
    r = np.asarray(scan.ranges)
    return np.asarray((r > scan.geometry.min_range) & (r < scan.geometry.max_range))


def _summary(figures: dict[str, float]) -> str:
    bands = [
        (
            int(figures[f"people_cells_unfiltered_{lo:g}-{hi:g}m"]),
            int(figures[f"people_cells_filtered_{lo:g}-{hi:g}m"]),
        )
        for lo, hi in RANGE_BANDS
    ]
    return (
        f"{100 * figures['corrupted_beams']:.0f} % of beams hit a visitor: people cells "
        f"{figures['people_cells_unfiltered']:.0f} -> {figures['people_cells_filtered']:.0f} "
        f"({100 * figures['people_cells_removed']:.1f} % removed, target >= 95 %); static cells kept "
        f"{100 * figures['static_kept']:.2f} % (target >= 99 %); people cells seen at <4 m, 4-8 m, >8 m "
        f"(unfiltered, filtered): {bands}; beams that hit a visitor left out "
        f"{100 * figures['person_beams_left_out']:.1f} % ("
        + ", ".join(
            f"{100 * figures[f'person_beams_left_out_{lo:g}-{hi:g}m']:.0f} %" for lo, hi in RANGE_BANDS
        )
        + f" at <4 m, 4-8 m, >8 m), other beams kept "
        f"{100 * figures['other_beams_kept']:.2f} %; endpoint cells "
        f"{figures['endpoint_cells_unfiltered']:.0f} -> {figures['endpoint_cells_filtered']:.0f}; "
        f"people / static cells hit in 1, 2, 3, 4, 5+ scans: "
        + ", ".join(f"{figures[f'confirm_people_hit_in_{k}_scans']:.0f}" for k in ("1", "2", "3", "4", "5+"))
        + " / "
        + ", ".join(f"{figures[f'confirm_static_hit_in_{k}_scans']:.0f}" for k in ("1", "2", "3", "4", "5+"))
        + "; confirmation rules (>= K scans within r cells) people cells left / static kept: "
        + _rules(figures)
    )


def _rules(figures: dict[str, float]) -> str:
    """The confirmation rules' people cells left and share of the static cells kept."""
    total = max(figures["static_kept_unfiltered_count"], 1)
    return ", ".join(
        f"r{r} K{k} {figures[f'confirm_r{r}_k{k}_people']:.0f} / "
        f"{100 * figures[f'confirm_r{r}_k{k}_static'] / total:.2f} %"
        for r, k in CONFIRM_RULES
    )


def _people_experiment(
    seed: int, max_scans: int | None, picture: Path, console: Console, modes: list[str]
) -> dict[str, object]:
    """Burgard et al. Fig. 10 on FHW with the peak crowd: people cells with and without filtering,
    for each filter mode (the first one's figures at the top level, its maps drawn); and the free
    sectors alone, without the tracker."""
    from tourbot.mapping.incremental import IncrementalMapper, MapperParams
    from tourbot.mapping.people_filter import PeopleFilterParams
    from tourbot.maps.reference import build_reference_map
    from tourbot.sim.overlay import OverlayConfig, overlay_crowd

    log = _read("fhw", max_scans)
    console.print("people filtering: laying the peak crowd over FHW ...")
    peak = OverlayConfig.preset("peak")
    crowded = overlay_crowd(log, build_reference_map(log), peak, seed=seed, preset="peak")
    console.print("people filtering: maps at the reference poses ...")
    clean, _, _ = _known_pose_maps(log, seed)
    result: dict[str, object] = {}
    per_mode: dict[str, dict[str, float]] = {}
    for k, mode in enumerate(modes):
        t0 = time.process_time()
        case = _people_maps(crowded.log, crowded.truth.corrupted, clean, seed, PeopleFilterParams.mode(mode))
        figures = {**case.figures, "cpu_s": time.process_time() - t0}
        per_mode[mode] = figures
        console.print(f"people filtering (FHW, peak crowd), mode {mode}: {_summary(figures)}")
        if k == 0:
            result.update(figures)
            result["mode"] = mode
            _draw_people_maps(
                case.plain, case.filtered, clean, case.truth, picture, f"FHW, peak crowd ({mode})"
            )
    result["modes"] = per_mode
    # the free sectors alone: no tracker, no beam left out
    sectors = IncrementalMapper(MapperParams(free_sectors=True), start=crowded.log.reference_poses[0])
    for scan, pose in zip(crowded.log.scans, crowded.log.reference_poses, strict=True):
        sectors.integrate(scan, pose)
    plain = IncrementalMapper(start=crowded.log.reference_poses[0])
    for scan, pose in zip(crowded.log.scans, crowded.log.reference_poses, strict=True):
        plain.integrate(scan, pose)
    truth = np.isfinite(_person_cells(crowded.log, crowded.truth.corrupted, clean))
    before = people_cells(_align_to(plain.grid(), clean), clean, truth)
    after = people_cells(_align_to(sectors.grid(), clean), clean, truth)
    result["sectors_only_people_cells"] = after["people"]
    result["sectors_only_static_kept"] = after["static_kept"] / max(before["static_kept"], 1)
    console.print(
        f"people filtering (FHW, peak crowd), free sectors alone (no tracker): people cells "
        f"{before['people']} -> {after['people']}, static cells kept "
        f"{100 * after['static_kept'] / max(before['static_kept'], 1):.2f} %"
    )
    console.print("people filtering: scan matching on the crowded log, with and without Eq. 12 ...")
    slam_params = PeopleFilterParams.mode(modes[0]) if modes else None
    result.update(_crowded_slam(crowded.log, seed, slam_params))
    console.print(
        f"people filtering (FHW, peak crowd): crowded SLAM relative error "
        f"{result['slam_trans_plain']:.3f} m plain, {result['slam_trans_filtered']:.3f} m with "
        f"Eq. 12 ({modes[0] if modes else 'default'}); picture: {picture}"
    )
    return result


def simulated_crowd_log(
    seconds: float, seed: int = 0, crowd: str = "peak", tour: str = "highlights"
) -> tuple[RobotLog, NDArray[np.bool_]]:
    """A guided ``tour`` of ``seconds`` in the shipped FHW site among ``crowd``, as ``tourbot
    simulate`` runs it (10 Hz, 360 beams); the log (true poses as reference) and, per scan, which
    beams returned from a visitor ``(S, B)``."""
    from tourbot.app.demo import start_pose_for
    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.sim.simulator import SimConfig
    from tourbot.site.default import default_site

    site = default_site()
    settings = SimulationSettings(crowd=crowd, seed=seed, sim=SimConfig(record=True))
    robot = simulated_runtime(site, settings, start=start_pose_for(site, tour), record=False)
    robot.runtime.start_tour(tour)
    robot.runtime.run(max_time=seconds)
    sim = robot.simulator
    return sim.to_robot_log(), np.asarray(sim.person_hit_history, dtype=bool)


def clean_map(log: RobotLog, person: NDArray[np.bool_]) -> OccupancyGrid:
    """The map of ``log`` at its reference poses without the beams in ``person`` ``(S, B)``."""
    from tourbot.mapping.incremental import IncrementalMapper

    ref = log.reference_poses
    mapper = IncrementalMapper(start=ref[0])
    for scan, pose, hit in zip(log.scans, ref, person, strict=True):
        mapper.integrate(scan, pose, keep=~hit)
    return mapper.grid()


def _people_sim_experiment(
    seeds: int, seconds: float, picture: Path, console: Console, modes: list[str]
) -> dict[str, float | list[dict[str, float | str]]]:
    """People filtering on the simulator's peak crowd at 10 Hz, where the tracker can follow the
    visitors: the same mapper, filter and metric as the FHW case, with the laser's ground truth,
    for each filter mode (the first one's maps drawn)."""
    from tourbot.mapping.people_filter import PeopleFilterParams

    runs: list[dict[str, float | str]] = []
    for seed in range(seeds):
        console.print(
            f"people filtering, simulated: {seconds:g} s of a tour in the peak crowd, seed {seed} ..."
        )
        log, person = simulated_crowd_log(seconds, seed)
        clean = clean_map(log, person)
        for k, mode in enumerate(modes):
            t0 = time.process_time()
            case = _people_maps(log, person, clean, seed, PeopleFilterParams.mode(mode))
            cpu = time.process_time() - t0
            figures = {"seed": seed, "scans": len(log), "cpu_s": cpu, **case.figures}
            runs.append({**figures, "mode": mode})
            console.print(f"people filtering, simulated, seed {seed}, mode {mode}: {_summary(figures)}")
            if seed == 0 and k == 0:
                _draw_people_maps(
                    case.plain, case.filtered, clean, case.truth, picture, "simulated FHW, peak crowd, 10 Hz"
                )
    out: dict[str, float | list[dict[str, float | str]]] = {"runs": runs, "seconds": seconds}
    for mode in modes:
        mine = [r for r in runs if r["mode"] == mode]
        before = sum(float(r["people_cells_unfiltered"]) for r in mine)
        after = sum(float(r["people_cells_filtered"]) for r in mine)
        out[f"people_cells_removed_{mode}"] = 1.0 - after / max(before, 1)
        out[f"static_kept_{mode}"] = float(np.mean([float(r["static_kept"]) for r in mine]))
    return out


def _crowded_slam(log: RobotLog, seed: int, params: PeopleFilterParams | None = None) -> dict[str, float]:
    """Scan matching on the crowded log without and with the people tracker (Eq. 12 weights)."""
    from tourbot.mapping.incremental import IncrementalMapper
    from tourbot.mapping.people_filter import PeopleFilteredMapper
    from tourbot.metrics import relative_pose_error

    start = log.reference_poses[0]
    plain = IncrementalMapper(start=start)
    filtered = PeopleFilteredMapper.create(_config(params), start=start, seed=seed)
    poses = []
    for scan in log.scans:
        plain.add_scan(scan)
        poses.append(filtered.add_scan(scan))
    ref = log.reference_poses
    a = relative_pose_error(np.asarray(plain.poses), ref)
    b = relative_pose_error(np.asarray(poses), ref)
    return {
        "slam_trans_plain": a.trans_mean,
        "slam_rot_plain_deg": float(np.degrees(a.rot_mean)),
        "slam_trans_filtered": b.trans_mean,
        "slam_rot_filtered_deg": float(np.degrees(b.rot_mean)),
    }


def _draw_people_maps(
    plain: OccupancyGrid,
    filtered: OccupancyGrid,
    clean: OccupancyGrid,
    truth: NDArray[np.bool_],
    path: Path,
    what: str,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tourbot.plotting import draw_map

    far = occupied_distance(clean) > 0.05
    fig, axes = plt.subplots(1, 2, figsize=(12, 7), constrained_layout=True)
    panels = ((axes[0], plain, "without people filtering"), (axes[1], filtered, "with people filtering"))
    for ax, grid, title in panels:
        draw_map(ax, grid)
        people = grid.occupied() & truth & far
        pts = grid.cell_to_world(np.argwhere(people))
        ax.plot(pts[:, 0], pts[:, 1], ".", color="crimson", ms=2, label=f"cells caused by people: {len(pts)}")
        ax.set_title(f"{what}: {title}")
        ax.legend(loc="upper right")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
