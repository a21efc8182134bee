"""CARMEN robot logs (plain text or gzip): a streaming reader and a writer.

A CARMEN log is one message per line, the message type first. The reader understands:

- ``ODOM x y theta tv rv accel timestamp host logger_timestamp``: raw wheel odometry;
- ``FLASER``/``RLASER n r1..rn x y theta odom_x odom_y odom_theta timestamp host logger_timestamp``:
  front/rear laser (old format; geometry from ``PARAM`` lines or CARMEN's guesses). ``x y theta``
  is the laser's pose (the robot's moved by ``robot_frontlaser_offset``): the reader takes it back
  to the robot's, the pose a scan's ``reference`` holds;
- ``RAWLASER1``..``RAWLASER4 type start_angle fov resolution max_range accuracy remission_mode n
  r1..rn m e1..em timestamp host logger_timestamp``: lasers with their geometry on the line;
- ``ROBOTLASER1``: as ``RAWLASER`` plus the laser and robot poses, velocities and safety distances;
- ``PARAM name value ...``: sensor parameters (field of view, resolution, maximum range, offset);
- ``#`` comments; other message types (``NEFF``, ``SYNC``, ``TRUEPOS``...) are skipped.

"Corrected" logs (a SLAM back end aligned every scan; see ``../shared/data/README.md``) put the
corrected pose on each laser line, and after each scan an extra ``ODOM`` line (timestamp zero, in
other logs garbage) repeats it; the timestamped readings that follow continue from that copy, so
the stream is re-anchored to the corrected trajectory at every scan and its error never grows.
A first pass (:func:`survey_odometry`) finds the copies by their pose (equal to the laser line's
beside them, whatever their timestamp) and whether the stream continues from them. By default
the reader then rebuilds raw odometry from the increments: it chains the motion between
consecutive readings and skips the jump onto each copy, so the wheel increments are kept and the
corrections dropped (``odometry="as-recorded"`` keeps the stream; one warning says which). Each
scan then has:

- ``odom``: that odometry interpolated at the scan's time (or, when the log has neither a
  timestamped stream nor copies, the odometry pose written on the laser line itself);
- ``reference``: the pose on the laser line, when the log has a separate odometry stream (or that
  pose differs from the line's own odometry pose); ``None`` otherwise.

Timestamps that are zero, repeated or going backwards make time interpolation meaningless: the
reader then matches each scan with the latest odometry reading before it in the file ("record
order") and says so in one warning. Timestamps that wrap around (32-bit seconds or milliseconds)
are unwrapped, stream by stream.

After reading, :func:`read_carmen` settles what the file leaves open and says why in the log's
``notes``: the unit of angle ``PARAM`` values (a field of view of 3.14159 is radians), the beam
layout (checked against the data: consecutive scans at the reference poses must agree, see
:mod:`tourbot.io.beam_geometry`; a log no layout explains is refused) and the maximum range (a
``PARAM`` cap the readings exceed, or one beyond every reading, gives way to the readings).

After the first pass (poses only), lines are parsed one at a time (``iter_carmen`` streams); a scan
is held back only until the odometry reading that follows it in time has been read.
"""

from __future__ import annotations

import gzip
import math
import re
import zlib
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, cast

import numpy as np

from tourbot.geometry import compose, interpolate_pose, invert, relative, wrap_angle
from tourbot.io.errors import LogFormatError
from tourbot.io.output import output_file
from tourbot.records import LaserGeometry, Odometry, Record, RobotLog, Scan

__all__ = [
    "DEFAULT_MAX_RANGE",
    "LASER_TYPES",
    "ODOMETRY_KINDS",
    "ODOMETRY_MODES",
    "CarmenReader",
    "OdometrySurvey",
    "guess_angle_increment",
    "guess_fov",
    "iter_carmen",
    "read_carmen",
    "survey_odometry",
    "write_carmen",
]

#: CARMEN's maximum range for old-format laser lines that carry no configuration (its ``readlog``).
DEFAULT_MAX_RANGE = 80.0

#: The laser message types the reader turns into scans.
LASER_TYPES = ("FLASER", "RLASER", "ROBOTLASER1", "RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")

#: How a reader treats a re-anchored odometry stream: rebuild it from its increments, or keep it.
ODOMETRY_MODES = ("rebuilt", "as-recorded")

#: What a log's odometry is once read: the stream as it was (no re-anchoring found), rebuilt from
#: the increments of a re-anchored stream, or a re-anchored stream kept as recorded.
ODOMETRY_KINDS = ("raw", "rebuilt", "re-anchored")
# whose pose an old-format laser line carries (PARAM tourbot_scan_pose)
SCAN_POSES = ("laser", "robot")

#: Timestamps wrap around at these (s): 32-bit unsigned and signed seconds, 32-bit milliseconds.
_WRAPS = (2.0**32, 2.0**31, 2.0**32 / 1000.0)

_IDENT = re.compile(r"^[A-Z][A-Z0-9_]*$")
_ROBOTLASER = re.compile(r"^ROBOTLASER[1-9]$")
_RAWLASER = re.compile(r"^RAWLASER[1-9]$")

Pose = tuple[float, float, float]


def guess_fov(num_beams: int) -> float:
    """Field of view (radians) of a SICK laser with ``num_beams`` beams, as CARMEN guesses it.

    180 and 360 beams mean the last beam of a 181/361-beam sweep was dropped (179 and 179.5
    degrees); 181 and 361 beams span 180 degrees; 400/401 beams span 100 degrees.
    """
    deg = math.pi / 180.0
    table = {181: 180.0 * deg, 180: 179.0 * deg, 361: 180.0 * deg, 360: 179.5 * deg}
    table |= {401: 100.0 * deg, 400: 99.75 * deg}
    return table.get(num_beams, math.pi)


def guess_angle_increment(num_beams: int) -> float:
    """Angle between two beams (radians), as CARMEN guesses it from the beam count."""
    if num_beams in (180, 181):
        return math.pi / 180.0
    if num_beams in (360, 361):
        return math.pi / 360.0
    if num_beams in (400, 401):
        return math.pi / 720.0
    return guess_fov(num_beams) / max(num_beams - 1, 1)


# --------------------------------------------------------------------------------------------------
# Reading


@dataclass
class _LaserParams:
    """What ``PARAM`` lines say about one old-format laser (``front`` or ``rear``)."""

    fov: float | None = None  # radians
    resolution: float | None = None  # radians
    max_range: float | None = None
    offset_x: float = 0.0
    # how the angles were read: (PARAM name, value as written, "degrees" or "radians", why)
    fov_read: tuple[str, float, str, str] | None = None
    resolution_read: tuple[str, float, str, str] | None = None
    max_range_param: str | None = None
    # tourbot's own exact (radian, unrounded) parameters, written by ``write_carmen``
    exact: dict[str, float] = field(default_factory=dict)


@dataclass
class _RawScan:
    """A laser line as read, before odometry is attached."""

    line: int
    timestamp: float
    ranges: np.ndarray
    geometry: LaserGeometry
    sensor: str
    pose: Pose | None  # the robot pose written on the line (corrected in corrected logs)
    line_odom: Pose | None  # the odometry pose written on the line, if any
    odom: Pose | None = None
    resolved: bool = False
    previous: Odometry | None = None  # the latest odometry reading read before this scan


class _MalformedError(Exception):
    """A malformed line: becomes a LogFormatError (strict) or a skipped record (lenient)."""

    def __init__(self, reason: str, field: str | None = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.field = field


def _open_binary(path: Path) -> IO[bytes]:
    with path.open("rb") as probe:
        magic = probe.read(2)
    if magic == b"\x1f\x8b":
        return cast(IO[bytes], gzip.open(path, "rb"))
    return path.open("rb")


def _number(token: str, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise _MalformedError(f"{token!r} is not a number", what) from None
    if not math.isfinite(value):
        raise _MalformedError(f"{token!r} is not a finite number", what)
    return value


def _count(token: str, what: str) -> int:
    try:
        value = int(token)
    except ValueError:
        raise _MalformedError(f"{token!r} is not a whole number", what) from None
    if value < 0:
        raise _MalformedError(f"negative count {value}", what)
    return value


def _ranges(tokens: list[str], start: int, n: int, kind: str) -> np.ndarray:
    chunk = tokens[start : start + n]
    try:
        ranges = np.array(chunk, dtype=np.float64)
    except ValueError:
        for i, tok in enumerate(chunk):
            _number(tok, f"range[{i}]")
        raise  # pragma: no cover - numpy and float() agree on what a number is
    bad = ~np.isfinite(ranges)
    if bad.any():
        i = int(np.argmax(bad))
        raise _MalformedError(f"{kind} range is {chunk[i]} (not a number)", f"range[{i}]")
    neg = ranges < 0.0
    if neg.any():
        i = int(np.argmax(neg))
        raise _MalformedError(f"{kind} range is negative ({chunk[i]})", f"range[{i}]")
    return ranges


def _need(tokens: list[str], count: int, kind: str, layout: str) -> None:
    if len(tokens) < count:
        raise _MalformedError(
            f"{kind} record too short: {len(tokens)} fields, at least {count} expected ({layout})"
        )


def _timestamp(tokens: list[str], index: int, kind: str) -> float:
    """The message's timestamp; the logger's timestamp (two fields later) when it is zero."""
    ts = _number(tokens[index], "timestamp")
    if ts == 0.0 and len(tokens) > index + 2:
        try:
            logger_ts = float(tokens[index + 2])
        except ValueError:
            raise _MalformedError(f"{kind} logger timestamp {tokens[index + 2]!r} is not a number") from None
        if math.isfinite(logger_ts):
            ts = logger_ts
    return ts


def _pose(tokens: list[str], start: int, names: Sequence[str]) -> Pose:
    """A pose from three fields, its angle wrapped to (-pi, pi] (left untouched when already in it)."""
    x, y, th = (_number(tokens[start + k], names[k]) for k in range(3))
    if not -math.pi < th <= math.pi:
        th = float(wrap_angle(th))
    return (x, y, th)


# --------------------------------------------------------------------------------------------------
# Re-anchored odometry

#: Two poses are "the same" (a copy) within these (the logs print 6 significant digits).
_COPY_TOL = 1e-4


@dataclass
class OdometrySurvey:
    """What a first pass over a log found about its ``ODOM`` stream.

    ``copies``: line numbers of ``ODOM`` lines that repeat the pose of the laser line next to them
    (right after it, or right before it in a log that puts them there; whatever their timestamp):
    copies of a scan's corrected pose, not odometry. ``real``: the other ``ODOM`` lines (``stamped``:
    those with a non-zero timestamp).
    ``misfit``: how far the step of the reading after each copy is from the step before it (wheel
    steps change little from one reading to the next), summed (m, plus 0.3 m per radian), with the
    step measured from the copy and from the reading before the copy. ``reanchored``: the stream
    continues from the copies (measured from them the steps fit better: measured from the reading
    before, each step would hold a correction); then raw odometry is the chain of increments that
    skips each jump onto a copy.
    """

    copies: set[int] = field(default_factory=set)
    real: int = 0
    stamped: int = 0  # real readings with a non-zero timestamp
    scans: int = 0
    anchored_scans: int = 0
    misfit: tuple[float, float] = (0.0, 0.0)
    tourbot: bool = False  # written by tourbot (its PARAM lines say how to read the odometry)

    @property
    def reanchored(self) -> bool:
        return bool(self.copies) and self.misfit[0] < self.misfit[1]


def _same_pose(a: Pose, b: Pose) -> bool:
    return (
        abs(a[0] - b[0]) <= _COPY_TOL
        and abs(a[1] - b[1]) <= _COPY_TOL
        and abs(float(wrap_angle(a[2] - b[2]))) <= _COPY_TOL
    )


def _laser_pose(tokens: list[bytes]) -> Pose | None:
    """The robot pose written on a FLASER/RLASER/ROBOTLASER line, None if it has none or is malformed."""
    try:
        kind = tokens[0]
        if kind in (b"FLASER", b"RLASER"):
            at = 2 + int(tokens[1])
        elif kind.startswith(b"ROBOTLASER"):
            n = int(tokens[8])
            at = 10 + n + int(tokens[9 + n]) + 3
        else:
            return None
        x, y, th = (float(t) for t in tokens[at : at + 3])
    except (ValueError, IndexError):
        return None
    return (x, y, th)


def survey_odometry(path: str | Path) -> OdometrySurvey:
    """Find the copies of the scans' poses in a log's ``ODOM`` stream, and whether it continues from them.

    The pattern is that of corrected logs (``../shared/data/README.md``): after each scan an ``ODOM``
    line (timestamp zero, or garbage) repeats the scan's corrected pose, and the timestamped
    readings continue from it. Copies are recognised by their pose alone, so real readings with
    zero or garbage timestamps are kept. Malformed lines are left to the main pass.
    """
    survey = OdometrySurvey()
    events: list[tuple[int, Pose, bool, bool]] = []  # (line, pose, is_laser, stamped)
    try:
        with _open_binary(Path(path)) as stream:
            for lineno, raw in enumerate(stream, start=1):
                head = raw[:12]
                if head.startswith(b"ODOM "):
                    tokens = raw.split()
                    try:
                        pose = (float(tokens[1]), float(tokens[2]), float(tokens[3]))
                        stamped = any(float(t) != 0.0 for t in tokens[7:10:2])
                    except (ValueError, IndexError):
                        continue
                    events.append((lineno, pose, False, stamped))
                elif head.startswith((b"FLASER ", b"RLASER ", b"ROBOTLASER")):
                    laser = _laser_pose(raw.split())
                    survey.scans += 1
                    if laser is not None:
                        events.append((lineno, laser, True, False))
                elif head.startswith(b"PARAM tourb"):
                    survey.tourbot = True
    except (OSError, EOFError, zlib.error, gzip.BadGzipFile):
        pass  # the main pass reports it, with the line

    # The copy of a scan's pose is the ODOM line right after its laser line (or, in a log that puts
    # them there, right before it).
    def neighbour(k: int, side: int) -> tuple[int, Pose, bool, bool] | None:
        j = k + side
        return events[j] if 0 <= j < len(events) and events[j][2] else None

    def match(k: int, side: int) -> tuple[int, Pose, bool, bool] | None:
        laser = neighbour(k, side)
        return laser if laser is not None and _same_pose(events[k][1], laser[1]) else None

    odoms = [k for k, e in enumerate(events) if not e[2]]
    n_after = sum(match(k, -1) is not None for k in odoms)
    n_before = sum(match(k, +1) is not None for k in odoms)
    # after the scan is the pattern; before it only where most scans have one (never by chance)
    side = +1 if n_before > n_after and n_before >= max(3, survey.scans // 2) else -1
    anchored: set[int] = set()
    recent: deque[Pose] = deque(maxlen=2)  # the last two real readings
    pending: Pose | None = None  # the latest copy since the last real reading
    misfit = [0.0, 0.0]  # how far the step after each copy is from the step before it, both ways
    for k in odoms:
        lineno, pose, _, stamped = events[k]
        copied = match(k, side)
        if copied is not None:
            survey.copies.add(lineno)
            anchored.add(copied[0])
            pending = pose
            continue
        survey.real += 1
        survey.stamped += stamped
        if pending is not None and len(recent) == 2:
            step_before = relative(recent[0], recent[1])
            for which, base in enumerate((pending, recent[1])):
                d = relative(base, pose) - step_before
                misfit[which] += math.hypot(d[0], d[1]) + 0.3 * abs(float(wrap_angle(d[2])))
        pending = None
        recent.append(pose)
    survey.anchored_scans = len(anchored)
    survey.misfit = (misfit[0], misfit[1])
    return survey


class CarmenReader:
    """Streams the records of one CARMEN log; iterate it once.

    After (or during) iteration, ``warnings`` holds the warnings (timestamps, skipped records),
    ``skipped`` the number of malformed records skipped in lenient mode, and ``defaulted_max_range``
    the sensors whose maximum range no record or ``PARAM`` line gave (``DEFAULT_MAX_RANGE`` used).
    """

    def __init__(self, path: str | Path, *, lenient: bool = False, odometry: str = "rebuilt") -> None:
        if odometry not in ODOMETRY_MODES:
            raise ValueError(f"odometry must be one of {', '.join(ODOMETRY_MODES)}, not {odometry!r}")
        self.path = Path(path)
        self.lenient = lenient
        self.warnings: list[str] = []
        self.skipped = 0
        self.defaulted_max_range: set[str] = set()
        self._first_skip: str | None = None
        self._content_lines = 0
        self._params = {"front": _LaserParams(), "rear": _LaserParams()}
        self._scan_odometry: str | None = None  # tourbot's PARAM: "line" or "none"
        self._scan_reference: str | None = None  # tourbot's PARAM: "line" or "none"
        # whose pose an old-format laser line carries: CARMEN's is the laser's; tourbot's files
        # say so in PARAM tourbot_scan_pose, and older ones (without it) carry the robot's
        self._line_pose: str | None = None
        self._tourbot_file = False
        self._geometries: dict[tuple[object, ...], LaserGeometry] = {}
        self._has_stream = False
        self.odometry = odometry
        self.survey = OdometrySurvey()
        self.odometry_kind = "raw"
        self._rebuilding = False
        self._lineno = 0
        # the rebuild: the rebuilt pose of the latest reading, and the raw pose its next increment
        # starts from (the latest reading, or the re-anchoring line after it)
        self._rebuilt: Pose | None = None
        self._chain_base: Pose | None = None
        # odometry matching
        self._record_order = False
        self._history: deque[Odometry] = deque(maxlen=512)
        self._queue: deque[Odometry | _RawScan] = deque()
        self._last_odom_time: float | None = None
        self._last_scan_time: dict[str, float] = {}
        self._wrap_offset: dict[str, float] = {}
        self._wrap_last: dict[str, float] = {}

    # -- public --------------------------------------------------------------------------------

    def __iter__(self) -> Iterator[Record]:
        if not self.path.exists():
            raise LogFormatError("no such file", path=self.path)
        if self.path.is_dir():
            raise LogFormatError("is a folder, not a CARMEN log file", path=self.path)
        self.survey = survey_odometry(self.path)
        # the laser lines' own odometry poses are used only in a log with neither a timestamped
        # stream nor copies (in corrected logs, found by their copies, those poses are corrected)
        sv = self.survey
        self._has_stream = sv.real > 0 and (sv.stamped > 0 or bool(sv.copies))
        self._note_survey()
        for lineno, tokens in self._lines():
            self._lineno = lineno
            try:
                item = self._parse(tokens)
            except _MalformedError as exc:
                self._malformed(exc, lineno)
                continue
            if isinstance(item, _RawScan):
                item.line = lineno
            if item is None:
                continue
            yield from self._push(item, lineno)
        if self._content_lines == 0:
            raise LogFormatError("empty file: no CARMEN records", path=self.path)
        yield from self._drain()
        if self.skipped:
            self.warnings.append(
                f"{self.path}: skipped {self.skipped} malformed record(s) (first: {self._first_skip})"
            )

    # -- lines ---------------------------------------------------------------------------------

    def _lines(self) -> Iterator[tuple[int, list[str]]]:
        """Non-empty, non-comment lines as tokens, with their line numbers.

        Each line is handed on only once the next one has been read, so that the last, cut-off
        line of a truncated gzip file is reported as a truncation rather than as a short record.
        """
        lineno = 0
        held: bytes | None = None
        try:
            with _open_binary(self.path) as stream:
                for raw in stream:
                    if held is not None:
                        tokens = self._tokens(held, lineno)
                        if tokens:
                            yield lineno, tokens
                    lineno += 1
                    held = raw
        except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
            reason = (
                "the gzip stream is truncated (the file was cut short)"
                if isinstance(exc, EOFError)
                else f"the gzip stream is corrupt ({exc})"
            )
            if not self.lenient:
                raise LogFormatError(reason, path=self.path, line=max(lineno, 1)) from None
            kept = max(lineno - 1, 0)
            self.warnings.append(f"{self.path}:{max(lineno, 1)}: {reason}; kept the {kept} lines before it")
            return
        if held is not None:
            tokens = self._tokens(held, lineno)
            if tokens:
                yield lineno, tokens

    def _tokens(self, raw: bytes, lineno: int) -> list[str]:
        if raw.strip():
            self._content_lines += 1
        if b"\x00" in raw:
            self._malformed(_MalformedError("binary data, not a line of CARMEN text"), lineno)
            return []
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            self._malformed(_MalformedError("binary data, not a line of CARMEN text"), lineno)
            return []
        tokens = text.split()
        if not tokens or tokens[0].startswith("#"):
            return []
        return tokens

    def _malformed(self, exc: _MalformedError, lineno: int) -> None:
        if not self.lenient:
            raise LogFormatError(exc.reason, path=self.path, line=lineno, field=exc.field)
        self.skipped += 1
        if self._first_skip is None:
            where = f"line {lineno}" + (f", field {exc.field}" if exc.field else "")
            self._first_skip = f"{where}: {exc.reason}"

    # -- parsing -------------------------------------------------------------------------------

    def _parse(self, tokens: list[str]) -> Odometry | _RawScan | None:
        kind = tokens[0]
        if kind == "ODOM":
            return self._parse_odom(tokens)
        if kind in ("FLASER", "RLASER"):
            return self._parse_old_laser(tokens)
        if _ROBOTLASER.match(kind) or _RAWLASER.match(kind):
            return self._parse_new_laser(tokens)
        if kind == "PARAM":
            self._parse_param(tokens)
            return None
        if not _IDENT.match(kind):
            shown = kind if len(kind) <= 20 else kind[:20] + "..."
            raise _MalformedError(f"unrecognised record {shown!r} (a CARMEN line starts with its type)")
        return None  # another CARMEN message type: not needed here

    def _parse_odom(self, tokens: list[str]) -> Odometry | None:
        _need(tokens, 8, "ODOM", "ODOM x y theta tv rv accel timestamp host logger_timestamp")
        pose = _pose(tokens, 1, ("x", "y", "theta"))
        tv = _number(tokens[4], "tv")
        rv = _number(tokens[5], "rv")
        _number(tokens[6], "accel")
        ts = _timestamp(tokens, 7, "ODOM")
        if self._scan_odometry is None and self._lineno in self.survey.copies:
            # a copy of a scan's corrected pose (see survey_odometry): not odometry; in a re-anchored
            # stream the next reading continues from it, so the next increment starts here
            if self.survey.reanchored:
                self._chain_base = pose
            return None
        if self._rebuilding:
            pose = self._rebuild(pose)
        return Odometry(timestamp=ts, pose=pose, tv=tv, rv=rv)

    def _rebuild(self, raw: Pose) -> Pose:
        """Chain the increment since the last reading (or re-anchoring line) onto the rebuilt path."""
        if self._rebuilt is None or self._chain_base is None:
            rebuilt = raw
        else:
            # rebuilt (+) (base (-) raw), in scalars: numpy's per-call cost is 10x the arithmetic here
            bx, by, bth = self._chain_base
            c, s = math.cos(bth), math.sin(bth)
            dx, dy = raw[0] - bx, raw[1] - by
            fx, fy, dth = c * dx + s * dy, -s * dx + c * dy, raw[2] - bth
            x, y, th = self._rebuilt
            c, s = math.cos(th), math.sin(th)
            heading = math.remainder(th + dth, 2.0 * math.pi)
            rebuilt = (x + c * fx - s * fy, y + s * fx + c * fy, heading if heading > -math.pi else math.pi)
        self._rebuilt = rebuilt
        self._chain_base = raw
        return rebuilt

    def _note_survey(self) -> None:
        """Decide how the odometry stream is read, and say so in one line."""
        sv = self.survey
        if sv.tourbot or not sv.copies:
            return
        found = (
            f"{self.path}: the ODOM stream repeats the corrected pose of {sv.anchored_scans} of "
            f"{sv.scans} scans on an extra line"
        )
        if not sv.reanchored:
            why = "the stream does not continue from them" if any(sv.misfit) else "too few readings to tell"
            self.warnings.append(f"{found}; the copies are left out, the stream kept ({why})")
        elif self.odometry == "rebuilt":
            self.odometry_kind = "rebuilt"
            self._rebuilding = True
            self.warnings.append(
                f"{found} and continues from it (re-anchored to the reference); raw odometry rebuilt from "
                "its increments, the jumps onto the copies dropped (--odometry-stream as-recorded keeps it)"
            )
        else:
            self.odometry_kind = "re-anchored"
            self.warnings.append(
                f"{found} and continues from it: kept as recorded (--odometry-stream as-recorded), so the "
                "odometry holds the reference's corrections and its error never grows"
            )

    def _parse_old_laser(self, tokens: list[str]) -> _RawScan:
        kind = tokens[0]
        layout = f"{kind} n r1..rn x y theta odom_x odom_y odom_theta timestamp host logger_timestamp"
        _need(tokens, 2, kind, layout)
        n = _count(tokens[1], "num_readings")
        _need(tokens, 2 + n + 7, kind, layout)
        if len(tokens) > 2 + n + 9:
            raise _MalformedError(
                f"{kind} record has {len(tokens)} fields, at most {2 + n + 9} expected for {n} readings"
            )
        ranges = _ranges(tokens, 2, n, kind)
        at = 2 + n
        pose = _pose(tokens, at, ("x", "y", "theta"))
        line_odom = _pose(tokens, at + 3, ("odom_x", "odom_y", "odom_theta"))
        ts = _timestamp(tokens, at + 6, kind)
        geometry = self._old_geometry(kind, n)
        return _RawScan(0, ts, ranges, geometry, kind, pose, line_odom)

    def _old_geometry(self, kind: str, n: int) -> LaserGeometry:
        which = "front" if kind == "FLASER" else "rear"
        p = self._params[which]
        ex = p.exact
        if "angle_increment" in ex:
            inc = ex["angle_increment"]
        elif p.resolution is not None and p.resolution * (n - 1) <= 2.0 * math.pi + 1e-9:
            inc = p.resolution
        elif p.fov is not None and n > 1:
            inc = p.fov / (n - 1)
        else:
            inc = guess_angle_increment(n)
        if "angle_min" in ex:
            amin = ex["angle_min"]
        elif p.fov is not None:
            amin = -0.5 * p.fov
        else:
            amin = -0.5 * math.pi  # CARMEN: old-format lasers start at -90 degrees
        if "max_range" in ex:
            max_range = ex["max_range"]
        elif p.max_range is not None:
            max_range = p.max_range
        else:
            max_range = DEFAULT_MAX_RANGE
            self.defaulted_max_range.add(kind)
        min_range = ex.get("min_range", 0.0)
        if all(k in ex for k in ("offset_x", "offset_y", "offset_theta")):
            offset = (ex["offset_x"], ex["offset_y"], ex["offset_theta"])
        else:
            offset = (p.offset_x, 0.0, 0.0 if which == "front" else math.pi)
        return self._geometry(n, amin, inc, max_range, min_range, offset)

    def _geometry(
        self, n: int, amin: float, inc: float, max_range: float, min_range: float, offset: Pose
    ) -> LaserGeometry:
        key = (n, amin, inc, max_range, min_range, offset)
        geometry = self._geometries.get(key)
        if geometry is None:
            geometry = LaserGeometry(n, amin, inc, max_range, min_range, offset)
            self._geometries[key] = geometry
        return geometry

    def _parse_new_laser(self, tokens: list[str]) -> _RawScan:
        kind = tokens[0]
        robot = kind.startswith("ROBOTLASER")
        head = f"{kind} type start_angle fov resolution max_range accuracy remission_mode n r1..rn m e1..em"
        tail = (
            " laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety side_safety"
            " turn_axis timestamp host logger_timestamp"
            if robot
            else " timestamp host logger_timestamp"
        )
        layout = head + tail
        _need(tokens, 9, kind, layout)
        _number(tokens[1], "laser_type")
        start = _number(tokens[2], "start_angle")
        fov = _number(tokens[3], "fov")
        res = _number(tokens[4], "angular_resolution")
        max_range = _number(tokens[5], "maximum_range")
        _number(tokens[6], "accuracy")
        _number(tokens[7], "remission_mode")
        n = _count(tokens[8], "num_readings")
        _need(tokens, 9 + n + 1, kind, layout)
        ranges = _ranges(tokens, 9, n, kind)
        m = _count(tokens[9 + n], "num_remissions")
        at = 10 + n + m
        extra = 11 if robot else 0
        _need(tokens, at + extra + 1, kind, layout)
        for k in range(m):
            _number(tokens[10 + n + k], f"remission[{k}]")
        if not max_range > 0:
            raise _MalformedError(f"{kind} maximum range must be positive, got {max_range}", "maximum_range")
        inc = res if res > 0 else (fov / (n - 1) if n > 1 else 0.0)
        pose: Pose | None = None
        offset: Pose = (0.0, 0.0, 0.0)
        if robot:
            laser_pose = _pose(tokens, at, ("laser_x", "laser_y", "laser_theta"))
            pose = _pose(tokens, at + 3, ("robot_x", "robot_y", "robot_theta"))
            for k, name in enumerate(("tv", "rv", "forward_safety", "side_safety", "turn_axis")):
                _number(tokens[at + 6 + k], name)
            rel = relative(pose, laser_pose)
            offset = (float(rel[0]), float(rel[1]), float(rel[2]))
        else:
            p = self._params["front" if kind == "RAWLASER1" else "rear"]
            if kind in ("RAWLASER1", "RAWLASER2"):
                offset = (p.offset_x, 0.0, 0.0 if kind == "RAWLASER1" else math.pi)
        ts = _timestamp(tokens, at + extra, kind)
        geometry = self._geometry(n, start, inc, max_range, 0.0, offset)
        return _RawScan(0, ts, ranges, geometry, kind, pose, pose)

    def _parse_param(self, tokens: list[str]) -> None:
        if len(tokens) < 3:
            raise _MalformedError("PARAM record needs a name and a value (PARAM name value ...)")
        name, value = tokens[1], tokens[2]
        if name.startswith("tourbot_"):
            self._tourbot_param(name[len("tourbot_") :], value)
            return
        key = name.lower().replace("_", "")
        which = "front" if "frontlaser" in key else "rear" if "rearlaser" in key else None
        if which is None:
            return
        try:
            number = float(value)
        except ValueError:
            return  # a parameter we do not use (e.g. a device name)
        if not math.isfinite(number):
            return
        p = self._params[which]
        if "offset" in key:
            p.offset_x = number
        elif "fov" in key and number > 0:
            # a laser scanner sees tens of degrees at least: 3.14159 is radians, 180 degrees
            radians = number <= 2.0 * math.pi + 1e-6
            why = "a field of view of at most 6.3 degrees is not a laser scanner's" if radians else ""
            p.fov = number if radians else math.radians(number)
            p.fov_read = (name, number, "radians" if radians else "degrees", why)
        elif "resolution" in key and number > 0:
            # scanners step by 0.25 degrees at the finest: 0.0174 is radians, 1 or 0.5 degrees
            radians = number < 0.1
            why = "a step under 0.1 degree is not a laser scanner's" if radians else ""
            p.resolution = number if radians else math.radians(number)
            p.resolution_read = (name, number, "radians" if radians else "degrees", why)
        elif ("maxrange" in key or key.endswith("max")) and number > 0:
            p.max_range = number
            p.max_range_param = name

    def _tourbot_param(self, name: str, value: str) -> None:
        if name == "odometry_kind":
            if value not in ODOMETRY_KINDS:
                raise _MalformedError(f"unknown odometry kind {value!r} ({', '.join(ODOMETRY_KINDS)})", name)
            self.odometry_kind = value
            return
        if name == "scan_odometry":
            self._scan_odometry = value
            return
        if name == "scan_reference":
            self._scan_reference = value
            self._tourbot_file = True
            return
        if name == "scan_pose":
            if value not in SCAN_POSES:
                raise _MalformedError(f"unknown scan pose {value!r} ({', '.join(SCAN_POSES)})", name)
            self._line_pose = value
            return
        for which, prefix in (("front", "flaser_"), ("rear", "rlaser_")):
            if name.startswith(prefix):
                self._params[which].exact[name[len(prefix) :]] = _number(value, name)

    # -- odometry matching ---------------------------------------------------------------------

    def _needs_stream(self, scan: _RawScan) -> bool:
        if self._scan_odometry is not None:
            return False
        return self._has_stream or scan.line_odom is None

    def line_pose_is_laser(self) -> bool:
        """Whether the pose on FLASER/RLASER lines is the laser's (CARMEN's convention).

        CARMEN's logger writes the laser's pose (the robot's moved forward by
        ``robot_frontlaser_offset``) on old-format laser lines, and the robot's odometry pose
        after it. Files tourbot wrote before it said which (no ``PARAM tourbot_scan_pose``)
        carry the robot's pose.
        """
        if self._line_pose is not None:
            return self._line_pose == "laser"
        return not self._tourbot_file

    def _finish_scan(self, scan: _RawScan) -> Scan:
        reference: Pose | None
        if self._scan_reference == "line":
            reference = scan.pose
        elif self._scan_reference == "none":
            reference = None
        elif scan.pose is not None and (self._has_stream or scan.pose != scan.line_odom):
            reference = scan.pose
        else:
            reference = None
        if reference is not None and scan.sensor in ("FLASER", "RLASER") and self.line_pose_is_laser():
            reference = _robot_from_laser(reference, scan.geometry.offset)
        if self._scan_odometry == "line":
            odom = scan.line_odom
        elif self._scan_odometry == "none":
            odom = None
        elif self._needs_stream(scan):
            odom = scan.odom
        else:
            odom = scan.line_odom
        return Scan(
            timestamp=scan.timestamp,
            ranges=scan.ranges,
            geometry=scan.geometry,
            odom=odom,
            reference=reference,
            sensor=scan.sensor,
        )

    def _fall_back(self, lineno: int, why: str) -> None:
        if self._record_order:
            return
        self._record_order = True
        self.warnings.append(
            f"{self.path}:{lineno}: timestamps {why}; odometry is matched to scans in record order "
            "(the latest odometry reading before each scan)"
        )

    def _unwrap(self, stream: str, ts: float, lineno: int) -> float:
        """A timestamp with the wrap-arounds of its stream (32-bit seconds or milliseconds) undone."""
        offset = self._wrap_offset.get(stream, 0.0)
        last = self._wrap_last.get(stream)
        if ts == 0.0:
            return ts  # zero means "no timestamp", handled by the caller
        t = ts + offset
        if last is not None:
            for modulus in _WRAPS:
                jump = t - last
                if abs(abs(jump) - modulus) < 0.01 * modulus:
                    offset -= math.copysign(modulus, jump)
                    t = ts + offset
                    self.warnings.append(
                        f"{self.path}:{lineno}: timestamps of {stream} wrap around ({last!r} then {ts!r}, "
                        f"a jump of {jump:+.6g} s); unwrapped by {modulus:g} s"
                    )
                    break
        self._wrap_offset[stream] = offset
        self._wrap_last[stream] = t
        return t

    def _push(self, item: Odometry | _RawScan, lineno: int) -> Iterator[Record]:
        if isinstance(item, Odometry):
            ts = self._unwrap("odometry", item.timestamp, lineno)
            if ts != item.timestamp:
                item = replace(item, timestamp=ts)
            last = self._last_odom_time
            if item.timestamp == 0.0:
                self._fall_back(lineno, "of odometry are zero")
            elif last is not None and item.timestamp <= last:
                what = "repeat" if item.timestamp == last else "go backwards"
                self._fall_back(lineno, f"of odometry {what} ({last!r} then {item.timestamp!r})")
            self._last_odom_time = item.timestamp
            self._history.append(item)
        else:
            item.timestamp = self._unwrap(f"{item.sensor} scans", item.timestamp, lineno)
            last_scan = self._last_scan_time.get(item.sensor)
            if item.timestamp == 0.0:
                self._fall_back(lineno, f"of {item.sensor} scans are zero")
            elif last_scan is not None and item.timestamp <= last_scan:
                what = "repeat" if item.timestamp == last_scan else "go backwards"
                self._fall_back(
                    lineno, f"of {item.sensor} scans {what} ({last_scan!r} then {item.timestamp!r})"
                )
            self._last_scan_time[item.sensor] = item.timestamp
            item.previous = self._history[-1] if self._history else None
            item.resolved = not self._needs_stream(item)
        self._queue.append(item)
        yield from self._flush(final=False)

    def _flush(self, *, final: bool) -> Iterator[Record]:
        while self._queue:
            head = self._queue[0]
            if isinstance(head, _RawScan) and not head.resolved and not self._resolve(head, final=final):
                return
            self._queue.popleft()
            yield head if isinstance(head, Odometry) else self._finish_scan(head)

    def _resolve(self, scan: _RawScan, *, final: bool) -> bool:
        """Attach the odometry at the scan's time; False while the reading after it is unread."""
        history = self._history
        if self._record_order:
            # the latest reading before the scan in the file, else the first one after it
            before = scan.previous
            if before is None and not history:
                if not final:
                    return False
                scan.odom = None
            else:
                scan.odom = before.pose if before is not None else history[0].pose
            scan.resolved = True
            return True
        if not history or history[-1].timestamp < scan.timestamp:
            if not final:
                return False
            scan.odom = history[-1].pose if history else None
            scan.resolved = True
            return True
        scan.odom = _interpolate(history, scan.timestamp)
        scan.resolved = True
        return True

    def _drain(self) -> Iterator[Record]:
        yield from self._flush(final=True)


def _robot_from_laser(laser: Pose, offset: Pose) -> Pose:
    """The robot's pose under a laser at ``laser`` mounted at ``offset`` (x, y in the robot's frame).

    The heading on the line is the robot's (the rear laser's turn is the geometry's, not the line's).
    """
    x, y, theta = invert((offset[0], offset[1], 0.0))
    robot = compose(laser, (x, y, theta))
    return (float(robot[0]), float(robot[1]), float(robot[2]))


def _laser_from_robot(robot: Pose, offset: Pose) -> Pose:
    """The inverse of :func:`_robot_from_laser`: the pose CARMEN writes on a laser line."""
    laser = compose(robot, (offset[0], offset[1], 0.0))
    return (float(laser[0]), float(laser[1]), float(laser[2]))


def _interpolate(history: deque[Odometry], t: float) -> Pose:
    """Odometry pose at time ``t`` from the recent readings (their times strictly increase)."""
    # scans come just before or after the latest readings: search back from the newest
    i = len(history) - 1
    while i > 0 and history[i - 1].timestamp >= t:
        i -= 1
    if i == 0:
        return history[0].pose
    a, b = history[i - 1], history[i]
    return interpolate_pose(a.pose, b.pose, (t - a.timestamp) / (b.timestamp - a.timestamp))


def iter_carmen(
    path: str | Path,
    *,
    lenient: bool = False,
    warnings: list[str] | None = None,
    odometry: str = "rebuilt",
) -> Iterator[Record]:
    """Stream the records (odometry readings and scans of every laser) of a CARMEN log in order.

    Malformed records raise :class:`LogFormatError` naming the file, line and field, or with
    ``lenient=True`` are skipped and counted. Warnings are appended to ``warnings`` when given.
    ``odometry``: ``"rebuilt"`` (raw odometry rebuilt from the increments of a re-anchored stream)
    or ``"as-recorded"``.
    """
    reader = CarmenReader(path, lenient=lenient, odometry=odometry)
    try:
        yield from reader
    finally:
        if warnings is not None:
            warnings.extend(reader.warnings)


def _infer_max_range(scans: list[Scan]) -> float | None:
    """The maximum range of a laser whose log does not state it: where readings pile up at the top.

    A SICK laser reports "no return" as its maximum reading, so many readings share the largest
    values; the smallest value (within 2 m of the largest) shared by at least 10 readings is taken
    as the maximum range. None when no such pile-up exists.
    """
    top = max(float(s.ranges.max()) for s in scans if s.ranges.size)
    near = np.concatenate([s.ranges[s.ranges >= top - 2.0] for s in scans])
    values, counts = np.unique(near, return_counts=True)
    piled = values[counts >= 10]
    return float(piled.min()) if piled.size else None


def read_carmen(
    path: str | Path, *, lenient: bool = False, laser: str | None = None, odometry: str = "rebuilt"
) -> RobotLog:
    """Read a whole CARMEN log (plain or gzip) into a :class:`RobotLog`.

    ``laser`` picks the laser (``FLASER``, ``RLASER``, ``ROBOTLASER1``, ``RAWLASER1``...); by
    default the first one in the file. Scans carry ``odom`` (raw odometry interpolated at the scan
    time) and, in corrected logs, ``reference`` (the corrected pose). When no record or ``PARAM``
    line gives the laser's maximum range it is inferred from the readings (see
    :func:`_infer_max_range`).

    A re-anchored odometry stream (corrected logs: the stream continues from a copy of each scan's
    corrected pose) is rebuilt from its increments unless ``odometry="as-recorded"``; the log's
    ``odometry_kind`` says which, and a warning says what was found.
    """
    reader = CarmenReader(path, lenient=lenient, odometry=odometry)
    scans: list[Scan] = []
    readings: list[Odometry] = []
    for record in reader:
        if isinstance(record, Odometry):
            readings.append(record)
        elif isinstance(record, Scan):
            scans.append(record)
    warnings = list(reader.warnings)
    if not scans:
        extra = f" ({reader.skipped} malformed records skipped)" if reader.skipped else ""
        raise LogFormatError(
            "no laser scans found (FLASER, RLASER, ROBOTLASER1 or RAWLASER1-4 records)" + extra,
            path=path,
        )
    sensors = list(dict.fromkeys(s.sensor for s in scans))
    chosen = laser or sensors[0]
    if chosen not in sensors:
        raise LogFormatError(f"no {chosen} scans in this log (it has: {', '.join(sensors)})", path=path)
    if len(sensors) > 1:
        others = ", ".join(f"{sum(s.sensor == o for s in scans)} {o}" for o in sensors if o != chosen)
        warnings.append(f"{path}: read the {chosen} scans; also holds {others} scans (choose with laser=)")
    scans = [s for s in scans if s.sensor == chosen]
    notes: list[str] = []
    scans = _settle_max_range(reader, chosen, scans, warnings, notes)
    log = RobotLog(
        source=str(path),
        scans=scans,
        odometry=readings,
        warnings=warnings,
        odometry_kind=reader.odometry_kind,
        notes=notes,
    )
    if reader.odometry_kind != "raw":
        found = (
            f"copies of the scan poses after {reader.survey.anchored_scans} of {reader.survey.scans} scans, "
            "the stream continuing from them"
        )
        said = "as PARAM tourbot_odometry_kind says"
        notes.append(f"odometry: {reader.odometry_kind} ({found if reader.survey.anchored_scans else said})")
    if chosen in ("FLASER", "RLASER") and log.has_reference:
        offset = scans[0].geometry.offset
        if reader.line_pose_is_laser():
            shift = f"{offset[0]:+g}, {offset[1]:+g} m" if offset[:2] != (0.0, 0.0) else "none"
            notes.append(
                f"reference poses: the laser's on the {chosen} lines (CARMEN's), taken back to the robot "
                f"by the laser's offset ({shift})"
            )
        else:
            notes.append(f"reference poses: the robot's on the {chosen} lines (a tourbot file)")
    log.scans = _settle_layout(reader, chosen, log, path)
    return log


def _with_geometry(scans: list[Scan], make: Callable[[LaserGeometry], LaserGeometry]) -> list[Scan]:
    cache: dict[LaserGeometry, LaserGeometry] = {}
    out = []
    for s in scans:
        g = cache.get(s.geometry)
        if g is None:
            g = cache[s.geometry] = make(s.geometry)
        out.append(s if g is s.geometry else replace(s, geometry=g))
    return out


def _settle_max_range(
    reader: CarmenReader, chosen: str, scans: list[Scan], warnings: list[str], notes: list[str]
) -> list[Scan]:
    """The laser's maximum range: stated, inferred from the readings, or a stated cap seen through."""
    params = reader._params["front" if chosen == "FLASER" else "rear"]
    stated = scans[0].geometry.max_range
    if chosen in reader.defaulted_max_range:
        piled = _infer_max_range(scans)
        if piled is None:
            notes.append(f"max range: {stated:g} m, CARMEN's default (no PARAM, no pile-up of readings)")
            return scans
        notes.append(f"max range: {piled:g} m, where readings pile up (the sensor's 'no return'; no PARAM)")
        return _with_geometry(scans, lambda g: replace(g, max_range=piled))
    if (
        chosen in ("FLASER", "RLASER")
        and params.max_range_param is not None
        and "max_range" not in params.exact
    ):
        ranges = np.concatenate([s.ranges for s in scans])
        top = _infer_max_range(scans) or float(ranges.max(initial=0.0))
        # returns beyond the stated range, short of the sensor's own "no return" value
        beyond = float(np.mean((ranges > stated * 1.001) & (ranges < top * 0.999))) if ranges.size else 0.0
        # a PARAM far beyond a pile-up of readings that most readings stay below (the "no return")
        returns_below = float(np.mean(ranges < top * 0.999)) if ranges.size else 0.0
        if stated > 2.0 * top and returns_below >= 0.5 and _infer_max_range(scans) is not None:
            warnings.append(
                f"{reader.path}: PARAM {params.max_range_param} {stated:g} m is beyond every reading, which "
                f"pile up at {top:g} m (the sensor's 'no return'; the PARAM is in another unit or wrong); "
                f"maximum range {top:g} m from the readings"
            )
            notes.append(f"max range: {top:g} m where the readings pile up (PARAM {stated:g} is implausible)")
            return _with_geometry(scans, lambda g: replace(g, max_range=top))
        if beyond > 0.01:
            inferred = top
            warnings.append(
                f"{reader.path}: PARAM {params.max_range_param} {stated:g} m is exceeded by "
                f"{100 * beyond:.0f} % of the readings (up to {top:g} m): read as a software cap, not "
                f"the sensor's range; maximum range {inferred:g} m from the readings"
            )
            notes.append(
                f"max range: {inferred:g} m from the readings (PARAM {stated:g} m is a cap they exceed)"
            )
            return _with_geometry(scans, lambda g: replace(g, max_range=inferred))
        notes.append(f"max range: {stated:g} m (PARAM {params.max_range_param})")
        return scans
    notes.append(f"max range: {stated:g} m (on the laser lines)")
    return scans


def _deg(rad: float) -> str:
    return f"{math.degrees(rad):+.2f}".rstrip("0").rstrip(".")


def _settle_layout(reader: CarmenReader, chosen: str, log: RobotLog, path: str | Path) -> list[Scan]:
    """Check the beam layout of an old-format laser against the data; refuse a log no layout fits."""
    from tourbot.io.beam_geometry import AGREEMENT, candidate_layouts, check_layouts

    scans = log.scans
    geometries = {s.geometry for s in scans}
    g = scans[0].geometry
    span = f"{_deg(g.angle_min)} to {_deg(g.angles[-1])} deg"
    if chosen not in ("FLASER", "RLASER"):
        notes_line = f"beams: {span}, from the laser lines' own start angle and resolution"
        log.notes.append(notes_line)
        return scans
    params = reader._params["front" if chosen == "FLASER" else "rear"]
    if "angle_increment" in params.exact:
        log.notes.append(f"beams: {span}, exactly as tourbot wrote them (PARAM tourbot_...)")
        return scans
    read = [r for r in (params.fov_read, params.resolution_read) if r is not None]
    said = "; ".join(f"PARAM {n} {v:g} read as {u}" + (f" ({why})" if why else "") for n, v, u, why in read)
    source = said or "CARMEN's convention for the beam count (no PARAM)"
    if len(geometries) > 1:
        log.notes.append(f"beams: {span} ({source}); not checked (the layout changes within the log)")
        return scans
    n = g.num_beams
    alternatives: dict[str, LaserGeometry] = {}
    if read:
        carmen_inc = guess_angle_increment(n)
        alternatives["CARMEN's convention (PARAM ignored)"] = replace(
            g, angle_min=-0.5 * math.pi, angle_increment=carmen_inc
        )
    if params.fov_read is not None and params.fov_read[2] == "radians" and n > 1:
        fov = math.radians(params.fov_read[1])
        alternatives["PARAM field of view read as degrees"] = replace(
            g, angle_min=-0.5 * fov, angle_increment=fov / (n - 1)
        )
    from_reference = log.has_reference
    poses = log.reference_poses if from_reference else log.odom_poses
    check = check_layouts(scans, poses, candidate_layouts(g, alternatives))
    frame = "reference poses" if from_reference else "odometry poses"
    if check is None:
        log.notes.append(
            f"beams: {span} ({source}); not checked (no two scans from known poses a little apart)"
        )
        return scans
    scores = ", ".join(
        f"{name}: {100 * v:.1f} cm"
        for name, v in check.scores.items()
        if name != check.chosen and not math.isnan(v)
    )
    best = check.scores[check.chosen]
    if not check.agrees:
        raise LogFormatError(
            f"no beam layout makes consecutive scans agree at the {frame} (best: {check.chosen}, "
            f"median {100 * best:.0f} cm apart, more than {100 * AGREEMENT:.0f} cm; {scores}); "
            "the laser's field of view and direction cannot be told",
            path=path,
        )
    layout = candidate_layouts(g, alternatives)[check.chosen]
    mirrored = layout.angle_increment < 0  # kept as the stated layout with each scan's ranges reversed
    fit = (
        f"consecutive scans at the {frame} agree to {100 * best:.1f} cm median over {check.pairs} pairs "
        f"({scores})"
    )
    if check.chosen == "stated":
        log.notes.append(f"beams: {span} ({source}); {fit}")
        return scans
    new_span = f"{_deg(layout.angle_min)} to {_deg(layout.angles[-1])} deg"
    if layout.angle_increment < 0:
        new_span += ", left to right: each scan's ranges reversed"
    log.warnings.append(
        f"{path}: the beams read as {span} ({source}) do not fit the data; read as {new_span} "
        f"({check.chosen}): {fit}"
    )
    log.notes.append(f"beams: {new_span} ({check.chosen}, not {span} from {source}); {fit}")
    if mirrored:
        scans = [replace(s, ranges=s.ranges[::-1].copy()) for s in scans]
    return scans if mirrored else _with_geometry(scans, lambda _g: layout)


# --------------------------------------------------------------------------------------------------
# Writing


def _fmt(values: Sequence[float]) -> str:
    """Floats written so that reading them back gives the same floats (shortest round-trip form)."""
    return " ".join(repr(float(v)) for v in values)


def _policy(values: list[Pose | None], what: str, path: str | Path) -> str:
    present = [v is not None for v in values]
    if all(present):
        return "line"
    if not any(present):
        return "none"
    raise LogFormatError(
        f"cannot write a CARMEN log where only some scans have a {what} pose "
        f"({sum(present)} of {len(present)})",
        path=path,
    )


def write_carmen(log: RobotLog, path: str | Path) -> None:
    """Write ``log`` as a CARMEN log (gzip when ``path`` ends in ``.gz``).

    Odometry readings become ``ODOM`` lines and scans ``FLASER`` (``RLASER`` for rear scans) lines
    with the laser's pose (CARMEN's convention: the reference moved by the laser's offset) and the
    scan's odometry pose; exact laser geometry and how to read the
    poses back go in ``PARAM tourbot_...`` lines, so ``read_carmen`` gives back the same log.
    Other lasers (RAWLASER, ROBOTLASER, ROS topics) are written as ``FLASER``, one laser at most.
    """
    path = Path(path)
    kinds = {s.sensor: ("RLASER" if s.sensor == "RLASER" else "FLASER") for s in log.scans}
    if len([k for k, v in kinds.items() if v == "FLASER"]) > 1:
        raise LogFormatError(
            f"cannot write several lasers as FLASER: {', '.join(sorted(kinds))}; keep one", path=path
        )
    odom_policy = _policy([s.odom for s in log.scans], "odometry", path)
    ref_policy = _policy([s.reference for s in log.scans], "reference", path)
    with output_file(path) as tmp, _open_for_writing(tmp) as out:
        out.write(f"# CARMEN log written by tourbot from {log.source}\n")
        out.write("# message formats defined: PARAM ODOM FLASER RLASER\n")
        out.write(f"PARAM tourbot_scan_odometry {odom_policy} nohost 0\n")
        out.write(f"PARAM tourbot_scan_reference {ref_policy} nohost 0\n")
        out.write(f"PARAM tourbot_odometry_kind {log.odometry_kind} nohost 0\n")
        out.write("PARAM tourbot_scan_pose laser nohost 0\n")
        current: dict[str, LaserGeometry] = {}
        odometry = log.odometry
        k = 0
        for scan in log.scans:
            while k < len(odometry) and odometry[k].timestamp <= scan.timestamp:
                _write_odom(out, odometry[k])
                k += 1
            kind = kinds[scan.sensor]
            if current.get(kind) != scan.geometry:
                _write_geometry(out, kind, scan.geometry)
                current[kind] = scan.geometry
            robot = scan.reference or scan.odom or (0.0, 0.0, 0.0)
            pose = _laser_from_robot(robot, scan.geometry.offset)  # CARMEN's: the laser's pose
            odom = scan.odom or robot
            ts = repr(float(scan.timestamp))
            out.write(
                f"{kind} {scan.ranges.size} {_fmt(scan.ranges.tolist())} {_fmt(pose)} {_fmt(odom)} "
                f"{ts} tourbot {ts}\n"
            )
        for reading in odometry[k:]:
            _write_odom(out, reading)


def _open_for_writing(path: Path) -> IO[str]:
    if path.name.endswith(".gz"):
        return cast(IO[str], gzip.open(path, "wt", encoding="utf-8", newline="\n", compresslevel=6))
    return path.open("w", encoding="utf-8", newline="\n")


def _write_odom(out: IO[str], o: Odometry) -> None:
    ts = repr(float(o.timestamp))
    out.write(f"ODOM {_fmt(o.pose)} {_fmt((o.tv, o.rv))} 0 {ts} tourbot {ts}\n")


def _write_geometry(out: IO[str], kind: str, g: LaserGeometry) -> None:
    prefix = "flaser" if kind == "FLASER" else "rlaser"
    values = {
        "angle_min": g.angle_min,
        "angle_increment": g.angle_increment,
        "max_range": g.max_range,
        "min_range": g.min_range,
        "offset_x": g.offset[0],
        "offset_y": g.offset[1],
        "offset_theta": g.offset[2],
    }
    for name, value in values.items():
        out.write(f"PARAM tourbot_{prefix}_{name} {float(value)!r} nohost 0\n")
