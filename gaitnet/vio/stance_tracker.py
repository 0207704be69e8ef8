"""Grouping of stance-foot candidates into stances, and left/right labels (thesis sec. 3.3.2).

D.-C. Dang's thesis separates left and right feet and groups the detections of one stance
period ((3.25), the sets ``S_left,l``) with "a simple tracking algorithm" it does not describe;
this module is the project's design.

Per frame the caller passes the candidates' floor points in the WORLD frame (moved with the
current pose estimate) and, optionally, the walking direction (the camera's optical axis
projected on the floor) and the camera position. :meth:`StanceTracker.update` returns per
candidate a :class:`StanceAssignment` ``(side, stance_id, is_new)``, or None while the
candidate is not (yet) part of a stance.

Grouping. A stance is a foot staying within ``assoc_radius_m`` of the same floor point.
Candidates are associated greedily (nearest first) with open tracks whose mean point is within
the radius; an unmatched candidate starts a tentative track, which becomes a stance once it has
been observed for ``confirm_s`` (a swing foot passing through the height band moves ~10 cm per
frame and never is); ``is_new`` is True on that frame (the filter augments the landmark then).
A track not observed for ``max_gap_s`` is closed: the foot left (lifted, or out of view). A
closed stance observed again within ``reopen_s`` at the same point (the foot was hidden by the
other leg) is re-opened under the same id instead of starting a duplicate.

Left/right. Labels come from a two-state Viterbi over all stances in order of their start,
re-run over the latest :data:`ONLINE_STANCES` whenever a stance is confirmed (so recent labels
may be corrected; :meth:`finish` returns the final ones). Pairwise costs between consecutive
stances ``a`` → ``b``, with ``d`` the lateral offset of ``b`` from ``a`` (positive to the right
of the walking direction; the difference of their offsets ``d_L`` from the walking line below,
which follows a curving or drifting path between stances a stride apart): different sides cost
``softplus(−s_b d / σ)`` (``s = +1`` right, ``−1`` left: a right foot lies to the right of the
left one), the same side costs ``same_side_cost + ½ (d / σ_same)²`` (normally feet alternate; a
missed stance breaks that, but then both lie on one line), and two stances down at the same time
(double support, standing) must differ (a large cost). Timing: two consecutive stances that
begin about one step time apart (the walk's median) cost ``step_timing_cost`` more on one side,
two step times apart (a stance missed between) on two. A unary term ``softplus(−s (d_L − b) /
σ_L)`` uses the offset ``d_L`` from the walking line: the mean camera position over the stance
and ``line_window_s`` either side of it (a step before and after, so the pelvis' sway towards
the stance foot cancels), less ``b``, the camera's own offset from the line between the feet (a
mount off the belly's middle): the midpoint of the mean offsets of the stances labelled left and
right, estimated from a first labelling with ``b = 0`` (when both sides are present). Where a
stance is missed, the two stances on either side of the gap lie on one line whatever their sides
and the pairwise costs cannot tell; the walking line and the timing can. This labels standing
(both feet down side by side), walking (alternation + step width) and one foot seen alone.
Candidates far to the side of the camera (``max_camera_offset_m``) are ignored: low objects on
the floor are not feet. A stance that begins where the stance before it rested, after it but too
soon for a swing (``same_foot_m``, ``same_foot_s``), or while it rests but closer to it than
``assoc_radius_m``, is that foot reported again (a track split when the pose jumps) and must
have its side: left to the other costs, the double-support term or the camera's offset could
label it the other foot (seen in simulation at the last step, where the end tag sheet corrects
the pose).

Final labels. The online labels use the world points of the observations, moved with the pose
of their frame; a drifting pose makes their lateral offsets wrong. :meth:`StanceTracker.sides_at`
labels the stances again at the positions the caller gives (the final landmark estimates).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from gaitnet.checks import check_positive, check_range

log = logging.getLogger(__name__)

__all__ = ["Stance", "StanceAssignment", "StanceParams", "StanceTracker"]

ONLINE_STANCES = 24
"""Stances :meth:`StanceTracker.update` labels again at each confirmation (about 12 strides;
:meth:`StanceTracker.finish` and :meth:`StanceTracker.sides_at` label all of them)."""


@dataclass(frozen=True)
class StanceParams:
    """Stance grouping and side labelling (tuned on simulated sessions det_s200–s205)."""

    assoc_radius_m: float = 0.04
    """A candidate within this distance [m] of a track's mean point belongs to it: a flat foot's
    detected point scatters by ~2 mm (benchmark), a pose drifting during a stance and the
    heel-strike-to-foot-flat roll add ~1–2 cm; swing feet move ~10 cm per frame."""
    confirm_s: float = 0.06
    """How long a track must have been observed (its latest observation's time minus its
    first's) before it is a stance [s]: its third frame at 30 Hz, its fifth at 60 Hz (a flat
    interval in walking lasts ~0.3 s; a swing foot passing through the height band moves ~10 cm
    per frame at 30 Hz, ~5 cm at 60 Hz, and does not stay within the radius that long); 0:
    at once. A count of frames (3 until 2026-11-28) confirmed stances twice as early at 60 Hz,
    so the landmark's first frame, which ``gaitnet infer``'s swing fill reads as the foot flat,
    came 0.05 s earlier against the foot's heel strike and the filled swings ran ahead (foot
    NMATE of the filled frames 9.1 / 5.4 cm on a simulated 60 Hz walk)."""
    weak_confirm_s: float = 0.1
    """How long a track seen only by weak candidates (small pieces of a foot, the toe of a
    stance foot under a flexed knee: :attr:`gaitnet.vio.feet.FootCandidate.weak`) must have
    been observed before it is a stance [s]; a track with one strong observation counts
    ``confirm_s`` from that one instead, so a landing shoe's first partial sight does not move
    the landmark's start (it is read as the foot flat) a frame earlier."""
    max_gap_s: float = 0.15
    """Close a track not observed for this long [s] (≈ 4 frames at 30 Hz)."""
    reopen_s: float = 1.0
    """A closed stance seen again at the same point within this time [s] is re-opened."""
    side_sigma_m: float = 0.03
    """Scale [m] of the lateral offset between consecutive opposite feet (step width
    ~0.05–0.15 m) in the side costs."""
    same_side_sigma_m: float = 0.04
    """Scale [m] of the lateral offset between consecutive stances of one foot (≈ 0)."""
    same_side_cost: float = 0.5
    """Extra cost of two consecutive stances on one side (a missed stance, or one foot seen
    alone), in nats: a weak alternation prior; the lateral offsets decide when the step width
    is more than ~3 cm."""
    tie_s: float = 0.05
    """Stances starting within this time [s] (standing: both feet found in the first frames)
    are chained in order of their last observation: the foot that stays down is next to the
    first step's stance."""
    line_sigma_m: float = 0.03
    """Scale [m] of the unary term on a stance's offset from the walking line (half a step
    width, 2.5–8 cm; the pelvis' sway left in the line averaged over ``line_window_s`` is about
    1 cm)."""
    line_window_s: float = 0.6
    """The walking line at a stance is the mean camera position from this long [s] before its
    first observation to this long after its last (about a step each way at 0.5–0.6 s a step)."""
    max_camera_offset_m: float = 0.4
    """Ignore candidates farther than this [m] to the side of the camera (needs ``p_CinW``):
    feet are within ~0.25 m of a waist camera's line; low clutter on the floor further out
    would otherwise become stances (seen in simulation: boxes ~0.9 m to the side)."""
    double_support_cost: float = 20.0
    """Cost of two stances that are down at the same time having one side."""
    same_foot_m: float = 0.08
    """A stance that begins within this distance [m] of where the stance before it rested,
    after that one was last seen but less than ``same_foot_s`` after, is the same foot reported
    again (its track split, e.g. when the pose jumps at a tag sheet): the two having different
    sides costs ``double_support_cost``. Two feet cannot rest on one spot in turn that quickly
    (their centres lie at least a shoe width, ~0.1 m, apart). So are two stances down at the
    same time less than ``assoc_radius_m`` apart (one foot found twice). 0: neither rule."""
    standing_overlap_s: float = 0.5
    """Two stances down together this long [s] (no walking double support lasts 0.3 s) are
    the two feet standing: the midpoint of their offsets from the walking line starts the
    side labelling (:meth:`StanceTracker._standing_bias`)."""
    same_foot_s: float = 0.2
    """See ``same_foot_m`` [s]: a foot lifted and set down elsewhere swings for 0.35–0.45 s."""
    segmented_radius_m: float = 0.15
    """A candidate from the segmenter's foot pixels within this distance [m] of a stance
    confirmed at a depth candidate (open, or closed less than ``reopen_s`` ago) is that foot
    and is ignored: the segmented point of a shoe lies 5–8 cm from its depth point (the toe
    cap's height seen along the ray), beyond ``assoc_radius_m``."""
    step_timing_cost: float = 1.0
    """Cost [nats] against two consecutive stances that begin one step time apart (the median
    gap between consecutive starts of 0.3–1.0 s) having one side, and against two that begin
    two step times apart (a stance missed between) having two; full at the multiple, none
    half a step off it; not for stances down at once or closer than ``same_foot_m``. Where a
    stance is missed on a walk that curves, the walking line and the lateral offsets may both
    mislead (the body leans into the curve, off the line between the feet); the timing does
    not. 0: off."""

    # keys of older configs and what took their place (named in the error)
    REPLACED_KEYS: ClassVar[dict[str, str]] = {
        "confirm_frames": "confirm_s (seconds a track must span; 0.06 is 3 frames at 30 Hz)",
        "camera_sigma_m": "line_sigma_m (the offset is now from the walking line; 0.03 m)",
    }

    def __post_init__(self) -> None:
        for name in ("assoc_radius_m", "side_sigma_m", "same_side_sigma_m", "line_sigma_m"):
            check_positive(name, getattr(self, name), " m")
        check_positive("max_camera_offset_m", self.max_camera_offset_m, " m")
        check_range("segmented_radius_m", self.segmented_radius_m, 0.0, 10.0, " m")
        check_range("step_timing_cost", self.step_timing_cost, 0.0, 100.0)
        for name in (
            "confirm_s",
            "weak_confirm_s",
            "max_gap_s",
            "reopen_s",
            "tie_s",
            "same_foot_s",
            "line_window_s",
            "standing_overlap_s",
        ):
            check_range(name, getattr(self, name), 0.0, 60.0, " s")
        for name in ("same_side_cost", "double_support_cost"):
            check_range(name, getattr(self, name), 0.0, 1e6)
        check_range("same_foot_m", self.same_foot_m, 0.0, 10.0, " m")


@dataclass(frozen=True)
class StanceAssignment:
    """What a candidate is: ``side`` ('left'/'right'), ``stance_id``, and ``is_new`` (True on
    the frame the stance is confirmed)."""

    side: str
    stance_id: int
    is_new: bool


@dataclass
class Stance:
    """One stance: ``xy`` the mean world floor point of its observations, times of the first
    and last observation, ``side``, the observations ``(t_s, xy)`` (including the tentative
    ones before confirmation), and ``strong``: whether a whole-enough foot was among them (not
    only weak candidates, :attr:`gaitnet.vio.feet.FootCandidate.weak`)."""

    id: int
    side: str
    xy: np.ndarray
    t_first: float
    t_last: float
    heading: np.ndarray
    obs: list[tuple[float, np.ndarray]] = field(default_factory=list, repr=False)
    strong: bool = False

    @property
    def n_obs(self) -> int:
        return len(self.obs)


@dataclass(eq=False)  # a track is itself: lists of tracks are searched by identity
class _Track:
    obs: list[tuple[float, np.ndarray]]
    stance: Stance | None = None
    closed: bool = False
    t_strong: float | None = None  # the first observation by a whole-enough foot (not weak)
    by_depth: bool = False  # confirmed at a candidate from depth (not from segmentation)

    def confirmable(self, t_s: float, params: StanceParams) -> bool:
        """Seen long enough to be a stance: ``confirm_s`` from its first strong observation,
        or ``weak_confirm_s`` from its first one when all were weak."""
        if self.t_strong is not None:
            return t_s - self.t_strong >= params.confirm_s
        return t_s - self.obs[0][0] >= params.weak_confirm_s

    @property
    def xy(self) -> np.ndarray:
        return np.mean([p for _, p in self.obs], axis=0)

    @property
    def t_last(self) -> float:
        return self.obs[-1][0]


def _assignment(kind: str, tr: _Track) -> StanceAssignment:
    """What :meth:`StanceTracker.update` reports for a candidate that ``tr`` took."""
    return StanceAssignment(tr.stance.side, tr.stance.id, kind == "new")  # type: ignore[union-attr]


def _softplus(x: float) -> float:
    return max(x, 0.0) + math.log1p(math.exp(-abs(x)))


class StanceTracker:
    """Online stance grouping and left/right labelling (module docstring)."""

    def __init__(self, params: StanceParams | None = None) -> None:
        self.params = params or StanceParams()
        self._open: list[_Track] = []
        self._closed: list[_Track] = []
        self._stances: list[Stance] = []
        self._heading = np.array([1.0, 0.0])
        self._path: list[
            tuple[float, float, float]
        ] = []  # the camera's (t, x, y) as update() saw it
        self._path_array = np.empty((0, 3))  # the same, built on demand

    @property
    def stances(self) -> list[Stance]:
        """Confirmed stances so far, in order of confirmation."""
        return list(self._stances)

    def update(
        self,
        t_s: float,
        candidates_xy: list[np.ndarray] | np.ndarray,
        heading_W: np.ndarray | None = None,
        p_CinW: np.ndarray | None = None,
        weak: Sequence[bool] | None = None,
        segmented: Sequence[bool] | None = None,
    ) -> list[StanceAssignment | None]:
        """Process one frame's candidates (world ``(x, y)``), return one entry per candidate.

        ``heading_W``: the walking direction on the floor (any length; e.g. the first two
        components of the camera's optical axis in the world); ``p_CinW``: the camera position
        (its first two components are used); ``weak``: per candidate, True for a small piece
        of a foot (:attr:`gaitnet.vio.feet.FootCandidate.weak`): a track becomes a stance
        ``confirm_s`` after its first strong observation, or ``weak_confirm_s`` after its first
        one when all were weak; ``segmented``: per candidate, True for one found in the
        segmenter's foot pixels where depth has none (:mod:`gaitnet.vio.feet_segmented`): it
        never joins a stance confirmed at a depth candidate, and is ignored within
        ``segmented_radius_m`` of one seen less than ``reopen_s`` ago (that foot is found; its
        segmented sightings would only move its start, end and point); it may confirm, and
        then go on observing, a track that depth saw too briefly (a landing shoe seen for two
        frames, then hidden).
        Frames must come in time order.
        """
        P = self.params
        if heading_W is not None:
            h = np.asarray(heading_W, dtype=np.float64)[:2]
            if np.linalg.norm(h) > 1e-6:
                self._heading = h / np.linalg.norm(h)
        xy = [np.asarray(c, dtype=np.float64)[:2] for c in candidates_xy]
        out: list[StanceAssignment | None] = [None] * len(xy)
        seg = [segmented is not None and bool(segmented[i]) for i in range(len(xy))]
        ignored = self._ignored(t_s, xy, p_CinW, seg)
        self._close_stale(t_s)
        # greedy nearest-first association with open tracks
        pairs = sorted(
            (float(np.linalg.norm(p - tr.xy)), i, j)
            for i, p in enumerate(xy)
            if i not in ignored
            for j, tr in enumerate(self._open)
            if not (seg[i] and tr.by_depth)
        )
        used_c: set[int] = set()
        used_t: set[int] = set()
        relabel = False
        for dist, i, j in pairs:
            if dist > P.assoc_radius_m or i in used_c or j in used_t:
                continue
            used_c.add(i)
            used_t.add(j)
            tr = self._open[j]
            tr.obs.append((t_s, xy[i]))
            if tr.t_strong is None and not (weak is not None and weak[i]):
                tr.t_strong = t_s
            if tr.stance is None and tr.confirmable(t_s, P):
                tr.by_depth = not seg[i]
                self._confirm(tr)
                relabel = True
                out[i] = ("new", tr)  # type: ignore[assignment]
            elif tr.stance is not None:
                self._sync(tr)
                out[i] = ("old", tr)  # type: ignore[assignment]
        for i, p in enumerate(xy):
            if i in used_c or i in ignored:
                continue
            out[i] = self._reopen_or_start(t_s, p, weak is not None and bool(weak[i]), seg[i])
            relabel = relabel or (out[i] is not None and out[i][0] == "new")  # type: ignore[index]
        if relabel:
            self._label_sides(ONLINE_STANCES)
        return [None if o is None else _assignment(*o) for o in out]  # type: ignore[misc]

    def finish(self) -> list[Stance]:
        """Close every track and return all stances with their final side labels."""
        for tr in self._open:
            if tr.stance is not None:
                tr.closed = True
                self._closed.append(tr)
        self._open = []
        self._label_sides()
        return self.stances

    # -- internals

    def _confirm(self, tr: _Track) -> None:
        xy = tr.xy
        tr.stance = Stance(
            id=len(self._stances),
            side="left",
            xy=xy,
            t_first=tr.obs[0][0],
            t_last=tr.t_last,
            heading=self._heading.copy(),
            strong=tr.t_strong is not None,
        )
        self._stances.append(tr.stance)
        self._sync(tr)
        log.debug("stance %d confirmed at (%.3f, %.3f)", tr.stance.id, xy[0], xy[1])

    @staticmethod
    def _sync(tr: _Track) -> None:
        st = tr.stance
        st.xy = tr.xy
        st.t_last = tr.t_last
        st.obs = list(tr.obs)

    def _ignored(
        self, t_s: float, xy: list[np.ndarray], p_CinW: np.ndarray | None, seg: list[bool]
    ) -> set[int]:
        """The candidates :meth:`update` ignores: too far to the side of the camera
        (``max_camera_offset_m``; the camera's position is also recorded for the walking
        line), or segmented near a stance found in depth (:meth:`_near_depth_stance`)."""
        out = set()
        if p_CinW is not None:
            cam = np.asarray(p_CinW, dtype=np.float64)[:2]
            self._path.append((float(t_s), float(cam[0]), float(cam[1])))
            right = np.array([self._heading[1], -self._heading[0]])
            limit = self.params.max_camera_offset_m
            out = {i for i, p in enumerate(xy) if abs((p - cam) @ right) > limit}
        return out | {i for i, p in enumerate(xy) if seg[i] and self._near_depth_stance(t_s, p)}

    def _close_stale(self, t_s: float) -> None:
        """Close the tracks not observed for ``max_gap_s``."""
        for tr in list(self._open):
            if t_s - tr.t_last > self.params.max_gap_s:
                self._open.remove(tr)
                if tr.stance is not None:
                    tr.closed = True
                    self._closed.append(tr)

    def _near_depth_stance(self, t_s: float, p: np.ndarray) -> bool:
        """Whether ``p`` lies within ``segmented_radius_m`` of a stance confirmed at a depth
        candidate, open or closed less than ``reopen_s`` ago."""
        P = self.params
        return any(
            tr.by_depth
            and t_s - tr.t_last <= P.reopen_s
            and np.linalg.norm(p - tr.xy) <= P.segmented_radius_m
            for tr in (*self._open, *self._closed)
        )

    def _reopen_or_start(
        self, t_s: float, p: np.ndarray, weak: bool, segmented: bool = False
    ) -> tuple[str, _Track] | None:
        """A candidate no open track took: it re-opens a closed stance at its point, or starts
        a track (a stance at once when ``confirm_s`` is 0 and it is not ``weak``)."""
        tr = self._reopen(t_s, p)
        if tr is not None:
            tr.obs.append((t_s, p))
            self._sync(tr)
            return "old", tr
        tr = _Track(obs=[(t_s, p)], t_strong=None if weak else t_s)
        self._open.append(tr)
        if tr.confirmable(t_s, self.params):
            tr.by_depth = not segmented
            self._confirm(tr)
            return "new", tr
        return None

    def _reopen(self, t_s: float, p: np.ndarray) -> _Track | None:
        P = self.params
        for tr in reversed(self._closed):
            if t_s - tr.t_last <= P.reopen_s and np.linalg.norm(p - tr.xy) <= P.assoc_radius_m:
                self._closed.remove(tr)
                tr.closed = False
                self._open.append(tr)
                return tr
        return None

    def sides_at(
        self,
        xy: Mapping[int, np.ndarray],
        camera_path: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> dict[int, str]:
        """Left/right of the stances whose ids are in ``xy``, labelled (module docstring) at
        the floor positions ``xy`` gives instead of the means of their observations, and
        against the walking line of ``camera_path`` ``(t_s (N,), p_CinW (N, ≥2))`` (the final
        camera poses, on the clock of :meth:`update`) instead of the path update() was given.

        The observations were moved to the world with the pose of their frame, and the pose
        drifts between corrections (by up to 15 cm sideways in simulated walks on
        textureless floors, where the odometry refuses most frames): the lateral offsets
        between consecutive stances, which decide the sides, are then wrong, and a correction
        during a stance splits it into two stances. Passing the final landmark estimates (the
        filter's, or better the smoother's) labels the stances where they are; the stances
        left out of ``xy`` (e.g. not reported) take no part. Call after :meth:`finish`."""
        chosen = [
            replace(st, xy=np.asarray(xy[st.id], dtype=np.float64)[:2])
            for st in self._stances
            if st.id in xy
        ]
        if camera_path is None:
            path = self._recorded_path()
            return self._labels(chosen, path[:, 0], path[:, 1:])
        t = np.asarray(camera_path[0], dtype=np.float64)
        W = self.params.line_window_s
        if chosen and not any(((t >= s.t_first - W) & (t <= s.t_last + W)).any() for s in chosen):
            log.warning(
                "the camera path misses the time of every stance (another clock?): the sides "
                "come from the offsets along the heading alone"
            )
        return self._labels(chosen, t, np.asarray(camera_path[1])[:, :2])

    def _label_sides(self, recent: int | None = None) -> None:
        """Label the stances (all, or the ``recent`` last confirmed: the online labels, which
        only the latest stances need, at a cost that does not grow with the walk)."""
        path = self._recorded_path()
        stances = self._stances if recent is None else self._stances[-recent:]
        labels = self._labels(stances, path[:, 0], path[:, 1:])
        for st in stances:
            st.side = labels[st.id]

    def _recorded_path(self) -> np.ndarray:
        """The camera's path update() was given, (N, 3) ``t, x, y`` (grown, not rebuilt)."""
        n = len(self._path_array)
        if n < len(self._path):
            self._path_array = np.concatenate([self._path_array, np.array(self._path[n:])])
        return self._path_array

    def _line_offsets(
        self, stances: list[Stance], path_t: np.ndarray, path_xy: np.ndarray
    ) -> dict[int, float | None]:
        """Each stance's offset to the right of the walking line (module docstring) [m]: from
        the mean camera position over its observations ± ``line_window_s``; None where the path
        has no point in that time (no camera positions given). Window means from cumulative
        sums: the labelling runs at every confirmation."""
        t = np.asarray(path_t, dtype=np.float64)
        xy = np.asarray(path_xy, dtype=np.float64).reshape(-1, 2)
        order = np.argsort(t, kind="stable")
        t, xy = t[order], xy[order]
        csum = np.concatenate([np.zeros((1, 2)), np.cumsum(xy, axis=0)])
        W = self.params.line_window_s
        out: dict[int, float | None] = {}
        for st in stances:
            i0 = int(np.searchsorted(t, st.t_first - W, side="left"))
            i1 = int(np.searchsorted(t, st.t_last + W, side="right"))
            if i1 <= i0:
                out[st.id] = None
                continue
            right = np.array([st.heading[1], -st.heading[0]])
            out[st.id] = float((st.xy - (csum[i1] - csum[i0]) / (i1 - i0)) @ right)
        return out

    def _labels(
        self, stances: list[Stance], path_t: np.ndarray, path_xy: np.ndarray
    ) -> dict[int, str]:
        """The sides of ``stances``: labelled with the camera's offset ``b`` from the line
        between the feet taken as 0, then, when both sides are present, again with ``b`` the
        midpoint of the two sides' mean offsets from the walking line (module docstring)."""
        d_line = self._line_offsets(stances, path_t, path_xy)
        labels = self._viterbi(stances, d_line, self._standing_bias(stances, d_line))
        left = [d for i, s in labels.items() if s == "left" and (d := d_line[i]) is not None]
        right = [d for i, s in labels.items() if s == "right" and (d := d_line[i]) is not None]
        if not left or not right:
            return labels
        return self._viterbi(stances, d_line, 0.5 * (float(np.mean(left)) + float(np.mean(right))))

    def _standing_bias(self, stances: list[Stance], d_line: Mapping[int, float | None]) -> float:
        """The camera's offset from the line between the feet as the feet standing side by
        side give it: the median midpoint of the line offsets of two stances down together
        for at least ``standing_overlap_s`` and at least ``same_foot_m`` apart across the
        walk (one of each foot); 0 without such a pair. The first labelling uses it: a
        camera worn 2–3 cm off the feet's middle otherwise puts a lone stance between two
        missed ones on the wrong side (a CMU walk, mirrored: 0 of 5 strides matched)."""
        P = self.params
        mids = []
        for i, a in enumerate(stances):
            for b in stances[i + 1 :]:
                da, db = d_line[a.id], d_line[b.id]
                together = min(a.t_last, b.t_last) - max(a.t_first, b.t_first)
                if (
                    da is not None
                    and db is not None
                    and together >= P.standing_overlap_s
                    and abs(da - db) >= P.same_foot_m
                ):
                    mids.append(0.5 * (da + db))
        return float(np.median(mids)) if mids else 0.0

    def _step_time(self, st: list[Stance]) -> float | None:
        """The walk's step time [s]: the median of the gaps between consecutive stances'
        starts that lie within 0.3–1.0 s (a step at any walking speed; a gap of two steps,
        a stance missed between, is longer at any but the fastest), None from fewer than 3."""
        gaps = np.diff([s.t_first for s in st])
        steps = gaps[(gaps >= 0.3) & (gaps <= 1.0)]
        return float(np.median(steps)) if len(steps) >= 3 else None

    def _transition(
        self, a: Stance, b: Stance, d_line: Mapping[int, float | None], step_s: float | None
    ) -> np.ndarray:
        """Costs ``[side of a, side of b]`` (left, right) of consecutive stances ``a`` → ``b``
        (module docstring)."""
        P = self.params
        h = a.heading + b.heading
        h = h / np.linalg.norm(h) if np.linalg.norm(h) > 1e-9 else b.heading
        da, db = d_line[a.id], d_line[b.id]
        if da is not None and db is not None:
            d = db - da
        else:
            d = float((b.xy - a.xy) @ np.array([h[1], -h[0]]))
        overlap = b.t_first <= a.t_last
        # a's foot again: b begins where a rested after a was last seen, too soon for a
        # swing, or both are down at once closer together than two candidates of one foot
        apart = float(np.linalg.norm(b.xy - a.xy))
        same_foot = (0.0 < b.t_first - a.t_last < P.same_foot_s and apart < P.same_foot_m) or (
            overlap and apart < min(P.assoc_radius_m, P.same_foot_m)
        )
        same = P.same_side_cost + 0.5 * (d / P.same_side_sigma_m) ** 2
        if overlap and not same_foot:
            same += P.double_support_cost
        other = [_softplus(-sb * d / P.side_sigma_m) for sb in (-1.0, 1.0)]
        if same_foot:
            other = [c + P.double_support_cost for c in other]
        if step_s is not None and not overlap and apart >= P.same_foot_m:
            n = (b.t_first - a.t_first) / step_s  # one step: two feet; two: one foot
            same += P.step_timing_cost * max(0.0, 1.0 - 2.0 * abs(n - 1.0))
            other = [c + P.step_timing_cost * max(0.0, 1.0 - 2.0 * abs(n - 2.0)) for c in other]
        return np.array([[same, other[1]], [other[0], same]])

    def _viterbi(
        self, stances: list[Stance], d_line: Mapping[int, float | None], bias: float
    ) -> dict[int, str]:
        """Two-state Viterbi over ``stances`` ordered by start time (module docstring), with
        the offsets ``d_line`` from the walking line (by id) less ``bias``: the side of each,
        by id. The lateral offset of a stance from the one before is the difference of their
        offsets from the walking line (which follows a curving or drifting path between two
        stances a stride apart), or, without a camera path, the offset along the mean
        heading."""
        P = self.params
        st = sorted(stances, key=lambda s: (s.t_first, s.id))
        for i in range(len(st) - 1):  # ties: the one that stays down longer goes second
            a, b = st[i], st[i + 1]
            if b.t_first - a.t_first <= P.tie_s and b.t_last < a.t_last:
                st[i], st[i + 1] = b, a
        if not st:
            return {}
        signs = (-1.0, 1.0)  # left, right

        def unary(s: Stance, sg: float) -> float:
            d = d_line[s.id]
            return 0.0 if d is None else _softplus(-sg * (d - bias) / P.line_sigma_m)

        step_s = self._step_time(st)
        cost = np.array([unary(st[0], sg) for sg in signs])
        back = []
        for a, b in zip(st[:-1], st[1:], strict=True):
            total = cost[:, None] + self._transition(a, b, d_line, step_s)
            arg = np.argmin(total, axis=0)
            cost = total[arg, [0, 1]] + np.array([unary(b, sg) for sg in signs])
            back.append(arg)
        j = int(np.argmin(cost))
        labels = [j]
        for arg in reversed(back):
            j = int(arg[j])
            labels.append(j)
        labels.reverse()
        return {s.id: "right" if j == 1 else "left" for s, j in zip(st, labels, strict=True)}
