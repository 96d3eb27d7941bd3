"""The browser viewer: a viser server that shows one robot, its screw axes, its PoE and its
Jacobian, and the :class:`Viewer` handle that :func:`view` returns.

Everything drawn comes from :mod:`poekin.viewer.scene` (poekin's own FK and Jacobians); this
module only puts it on the page. Each part of the robot is sent once, as a child of its body's
scene node; a configuration change then sends poses and the panel's texts only. The model's
meshes are read in a background thread, so the page is usable before they arrive.

Needs viser (the extra ``view``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import ipaddress
import math
import os
import threading
import time
import webbrowser
from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np
import viser
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import Chain, JacobianConvention
from poekin.collision.obstacles import Obstacle, as_obstacles
from poekin.dh import Convention, DHTable
from poekin.errors import InputError, PoekinError, did_you_mean
from poekin.io.trajectory import Trajectory, trajectory_from
from poekin.tree import Tree
from poekin.viewer import panel, wholebody
from poekin.viewer.collision import (
    DEFAULT_MARGIN,
    CollisionScene,
    CollisionState,
    collision_scene,
    shapes,
)
from poekin.viewer.geometry import Geometry, Part, mjcf_geometry, stand_in, urdf_geometry
from poekin.viewer.ik import Reach, follow, ghost_poses, pick, reach, support
from poekin.viewer.loading import Shown, load_params_comparison, load_shown
from poekin.viewer.play import Clock, Playback, playback_of, tool_trace
from poekin.viewer.scene import (
    Comparison,
    Control,
    Form,
    Snapshot,
    Subject,
    axis_pose,
    controls,
    dh_frames,
    ghost,
    jacobian,
    joint_anchors,
    make_subject,
    manipulability,
    nearest_point,
    screw_kind,
    snapshot,
)
from poekin.viewer.wholebody import Handles, WholeBodyReach

__all__ = ["Viewer", "is_loopback", "view"]

FloatArray = NDArray[np.float64]
Unit = Literal["rad", "deg"]

DEFAULT_PORT = 8080
MODEL_COLOR = (10, 50, 150)  # a deep blue: three.js lighting pales colours
YOURS_COLOR = (235, 110, 0)  # orange, as in poekin's diagnosis figure
MISMATCH_COLOR = (200, 20, 20)
PARTIAL_COLOR = (110, 40, 170)
DH_COLOR = (0, 130, 130)
LEVER_COLOR = (110, 110, 110)
TARGET_COLOR = (20, 170, 60)  # the IK target, reached
UNREACHABLE_COLOR = (225, 20, 20)  # the IK target, out of reach
SOLUTION_COLOR = (40, 170, 120)  # the other closed-form solutions, as ghosts
SOLUTION_OPACITY = 0.28
HELD_COLOR = (30, 110, 220)  # a whole-body handle's held frame, met
TRACE_COLOR = (190, 30, 150)  # the tool trace of a trajectory played
STOP_COLOR = (200, 20, 20)  # where its path stopped
COLLISION_COLOR = (40, 170, 210)  # the robot's collision geoms, see-through
COLLISION_OPACITY = 0.4
OBSTACLE_COLOR = (160, 130, 95)  # world obstacles
OBSTACLE_OPACITY = 0.6
COLLIDING_COLOR = (225, 20, 20)  # a shape in a pair that penetrates
WITNESS_COLOR = (255, 215, 0)  # the witness points of a pair that penetrates: on red, yellow
NEAR_COLOR = (255, 120, 0)  # those of a pair closer than the margin, apart
_MARGIN_MAX_MM = 100.0
_PLAY_FPS = 30.0  # frames a second while a trajectory plays
_SYMBOL = {"space": "S", "body": "B"}
_NO_SOLUTION = "(pick one)"
_REVOLUTE_STEP = 1e-4  # rad: four decimals in the number box
_DEGREE_STEP = 0.01
_SLIDE_STEP = 1e-4  # m


#: Debian's Chromium, and how the tests, the benchmark and the README's screenshots start it
#: headless on a machine without a GPU or a network: WebGL in software (SwiftShader), and none of
#: Chromium's own connections. Never ``playwright install``, which downloads a browser.
HEADLESS_CHROMIUM = "/usr/bin/chromium"
HEADLESS_CHROMIUM_ARGS = (
    "--no-sandbox",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)


def is_loopback(host: str) -> bool:
    """Whether ``host`` is only reachable from this machine (``localhost``, 127.0.0.0/8, ::1)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _quat(R: FloatArray) -> FloatArray:
    return np.asarray(lie.rotation_to_quat(R), dtype=np.float64)


def _rpy_rotation(roll: float, pitch: float, yaw: float) -> FloatArray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``."""
    exp = lie.exp_so3
    R = exp([0.0, 0.0, yaw]) @ exp([0.0, pitch, 0.0]) @ exp([roll, 0.0, 0.0])
    return np.asarray(R, dtype=np.float64)


@dataclasses.dataclass
class _Node:
    """A scene node this viewer made, and what it stands for (for tests and the handle)."""

    handle: Any
    kind: str  # body, frame, end, home, screw, partial, dh, ghost_link, ghost_screw, ...
    index: int = -1
    opacity: float = 1.0  # a part's own


class Viewer:
    """A running viewer of one robot, as :func:`view` returns it.

    ``q`` gets and sets the configuration (MuJoCo's ``qpos`` layout; a bare parameter set: its
    joint values); every drawn frame, screw axis and readout follows. ``url`` is the page,
    ``close()`` stops the server. In a Jupyter notebook the handle shows the page inline.

    For tests and scripts: :meth:`node_poses` gives the world pose of every scene node, and
    :meth:`texts` the panel's readouts, exactly as sent to the page.
    """

    def __init__(
        self,
        subject: Subject,
        *,
        geometry: Callable[[Subject], Geometry],
        comparison: Comparison | None = None,
        handles: Handles | None = None,
        playback: Playback | None = None,
        collision: bool = False,
        obstacles: Obstacle | Sequence[Obstacle] = (),
        host: str = "127.0.0.1",
        port: int | None = None,
    ) -> None:
        self.subject = subject
        self._obstacles = as_obstacles(obstacles)
        self._collision_scene: CollisionScene | None = None
        self._collision_state: CollisionState | None = None
        self._collision_s: float | None = None
        if collision or self._obstacles:  # said before the server starts
            self._collision_scene = _collision_scene_of(subject, self._obstacles)
        if handles is not None and subject.tree is None:
            raise InputError("whole-body IK needs a tree: a model, not a bare parameter set")
        self._handles = handles
        self._wb: WholeBodyReach | None = None
        self._wb_solve_s: float | None = None
        self._wb_note = ""
        self.comparison = comparison
        self._tool_on = (subject.frame, subject.tool)  # the tool rides on this frame only
        self._geometry_fn = geometry
        self._lock = threading.RLock()
        self._nodes: dict[str, _Node] = {}
        self._qpos = subject.qpos0
        self._playback = playback
        self._clock: Clock | None = None
        self._player: threading.Thread | None = None
        if playback is not None:
            self._clock = Clock(playback.start, playback.end, playback.start)
            self._qpos = playback.qpos_at(playback.start)
        self._form: Form = "space"
        self._k = subject.n_joints
        self._unit: Unit = "rad"
        self._convention: JacobianConvention = "space"
        self._dh_convention: Convention = "standard"
        self._aligned = False
        self._syncing = False
        self._texts: dict[str, str] = {}
        self._pending: list[tuple[str, FloatArray]] = []
        self._geometry: Geometry | None = None
        self._geometry_ready = threading.Event()
        self._rng = np.random.default_rng(0)
        self._closed = False
        self._extent = subject.extent
        self._ik_support = support(subject)
        self._reach: Reach | None = None
        self._ik_solve_s: float | None = None
        self._solution_meshes = False
        self.server = _start_server(host, port)
        self.host = host
        self.port = int(self.server.get_port())
        self._controls = controls(subject)
        try:
            with self.server.atomic():
                self._build_scene()
                self._build_gui(collision)
                self._refresh()
                self._sync_controls()
        except BaseException:
            self.close()
            raise
        self._loader = threading.Thread(
            target=self._load_geometry, name="poekin-geometry", daemon=True
        )
        self._loader.start()

    # --- the handle -------------------------------------------------------------------------

    @property
    def url(self) -> str:
        """The page's address (``localhost`` for a server on all interfaces)."""
        host = "localhost" if self.host in ("0.0.0.0", "::") else self.host
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.port}"

    @property
    def q(self) -> FloatArray:
        """The configuration shown: ``(nq,)`` in MuJoCo's ``qpos`` layout (a copy)."""
        return np.array(self._qpos, dtype=np.float64)

    @q.setter
    def q(self, qpos: ArrayLike) -> None:
        x = self.subject.check_qpos(qpos)
        with self._lock:
            self._qpos = x
            self._wb = None  # the whole-body targets: at their frames
            self._refresh()
            self._sync_controls()

    @property
    def frame(self) -> str:
        """The end frame: a body or site of the model."""
        return self.subject.frame

    @property
    def form(self) -> Form:
        """``"space"`` (labels ``S_i``, the twists in world coordinates) or ``"body"``."""
        return self._form

    @form.setter
    def form(self, form: Form) -> None:
        self._form_input.value = {"space": "space (S_i)", "body": "body (B_i)"}[form]

    @property
    def step(self) -> int:
        """The PoE step ``k``: the partial product ``T_k`` shown (``0..n``)."""
        return self._k

    @step.setter
    def step(self, k: int) -> None:
        if not 0 <= k <= self.subject.n_joints:
            raise InputError(f"the PoE step k must be in 0..{self.subject.n_joints}, got {k}")
        self._step_input.value = int(k)

    @property
    def geometry(self) -> Geometry | None:
        """The robot's parts, once loaded (None before)."""
        return self._geometry

    def wait_geometry(self, timeout: float = 30.0) -> Geometry:
        """Block until the robot's parts are on the page; return them."""
        if not self._geometry_ready.wait(timeout):
            raise TimeoutError(f"the robot's geometry did not load within {timeout} s")
        assert self._geometry is not None
        return self._geometry

    def options(self) -> dict[str, Any]:
        """The panel's settings by their label: ``{"form": "space (S_i)", "DH frames": False,
        ...}``."""
        return {name: handle.value for name, handle in self._options.items()}

    def set_option(self, name: str, value: Any) -> None:
        """Change a panel setting, as the page's control of that label does (the page shows it
        too): e.g. ``set_option("DH frames", True)``, ``set_option("Jacobian", "body")``.

        Raises:
            InputError: no such setting, or a value the control cannot show: a choice not in
                its list, not True or False for a check box, not a number in a slider's range.
                The message lists the valid ones.
        """
        if name not in self._options:
            raise InputError(f"no panel setting {name!r}: {did_you_mean(name, self._options)}")
        handle = self._options[name]
        if handle is self._ik_input and value is True:
            self._check_ik()
        choices = getattr(handle, "options", None)
        if choices is not None:  # a dropdown
            if value not in choices:
                raise InputError(
                    f"{name!r} has no choice {value!r}: {did_you_mean(str(value), choices)}"
                )
        elif isinstance(handle.value, bool):  # a check box
            if not isinstance(value, bool | np.bool_):
                raise InputError(f"{name!r} is a check box: give True or False, got {value!r}")
            value = bool(value)
        else:  # a slider
            lo, hi = handle.min, handle.max
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float | np.integer | np.floating)
                or not lo <= value <= hi
            ):
                raise InputError(f"{name!r} takes a number in [{lo:g}, {hi:g}], got {value!r}")
        handle.value = value

    def snapshot(self) -> Snapshot:
        """What is drawn now (:func:`poekin.viewer.scene.snapshot` at :attr:`q`)."""
        return snapshot(self.subject, self._qpos)

    # --- a trajectory played -------------------------------------------------------------------

    @property
    def playback(self) -> Playback | None:
        """The trajectory played (:class:`poekin.viewer.play.Playback`), or None without one
        (``view(..., play=...)``)."""
        return self._playback

    @property
    def playing(self) -> bool:
        """Whether the trajectory is playing (in real time, from a thread of the viewer)."""
        return self._clock is not None and self._clock.playing

    @property
    def play_time(self) -> float:
        """The trajectory's time shown, s; setting it shows the robot there (as the time
        slider does), playing on from it if playing.

        Raises:
            InputError: no trajectory, or a time outside ``[t[0], t[-1]]``.
        """
        return self._need_clock().at(time.monotonic())

    @play_time.setter
    def play_time(self, seconds: float) -> None:
        clock = self._need_clock()
        if not clock.start <= seconds <= clock.end:
            raise InputError(
                f"the trajectory's time runs from {clock.start:g} to {clock.end:g} s, got "
                f"{seconds!r}"
            )
        with self._lock:
            clock.seek(seconds, time.monotonic())
            self._show_time(clock.time)

    def play(self) -> None:
        """Play the trajectory in real time from the time shown (from its start when at its
        end), as the page's play button does; it stops at the end."""
        clock = self._need_clock()
        with self._lock:
            if clock.playing:
                return
            clock.play(time.monotonic())
            self._show_time(clock.time)
            self._play_button.label = "pause"
            self._player = threading.Thread(
                target=self._run_player, name="poekin-play", daemon=True
            )
            self._player.start()

    def pause(self) -> None:
        """Hold the trajectory at the time reached."""
        clock = self._need_clock()
        with self._lock:
            clock.pause(time.monotonic())
            self._play_button.label = "play"
            self._show_time(clock.time)

    def _need_clock(self) -> Clock:
        if self._clock is None:
            raise InputError("no trajectory to play: start the viewer with play=FILE (--play)")
        return self._clock

    def _run_player(self) -> None:
        """Advance the shown time until the end, a pause or the viewer closes."""
        clock = self._clock
        assert clock is not None
        while True:
            with self._lock:
                if self._closed or not clock.playing:
                    return
                self._show_time(clock.tick(time.monotonic()))
                if not clock.playing:  # the end
                    self._play_button.label = "play"
                    return
            time.sleep(1.0 / _PLAY_FPS)

    def _show_time(self, seconds: float) -> None:
        """The robot at ``seconds`` of the trajectory, the slider there."""
        assert self._playback is not None
        self._qpos = self._playback.qpos_at(seconds)
        self._wb = None  # the whole-body targets: at their frames
        self._syncing = True
        try:
            _set(self._time_input, "value", seconds)
        finally:
            self._syncing = False
        self._refresh()
        self._sync_controls()

    def _on_time(self) -> None:
        """The time slider moved on the page."""
        if self._syncing or self._clock is None:
            return
        with self._lock:
            seconds = float(self._time_input.value)
            if seconds == self._clock.time:
                return  # an update already shown
            self._clock.seek(seconds, time.monotonic())
            self._show_time(self._clock.time)

    def _refresh_trace(self) -> None:
        """The trace and the stop marker for the end frame shown."""
        assert self._playback is not None
        points = self._trace_points()
        self._nodes["/play/trace"].handle.points = np.stack(
            [points[:-1], points[1:]], axis=1
        ).astype(np.float32)
        stop = self._playback.trajectory.stop_time
        if stop is not None:
            self._nodes["/play/stop"].handle.position = points[self._playback.index(stop)]

    # --- the IK mode ------------------------------------------------------------------------

    @property
    def reach(self) -> Reach | None:
        """What the IK mode shows (:class:`poekin.viewer.ik.Reach`: the target, the
        configuration, success, the residual, the closed-form solutions), or None when the
        mode is off."""
        return self._reach if self._ik_input.value else None

    @property
    def target(self) -> FloatArray | None:
        """The IK target ``T_world_target`` ``(4, 4)`` (a copy), or None when the mode is off."""
        shown = self.reach
        return None if shown is None else shown.target.copy()

    def set_target(self, T_world_target: ArrayLike) -> Reach:
        """Put the IK target at ``T_world_target`` ``(4, 4)`` (world frame) and solve for it
        from the configuration shown, as a drag of the target handle does: the arm, the
        sliders, the handle, the ghosts of the other solutions and the residual all follow.
        Turns the IK mode on.

        Returns:
            What is shown (:attr:`reach`): ``success`` False and the best fit for a target
            out of reach.

        Raises:
            InputError: the IK mode does not apply to this end frame (the reason), or a target
                that is not a finite rigid transform.
        """
        with self._lock:
            self._check_ik()
            shown = self._solve(T_world_target)  # validates before anything changes
            if not self._ik_input.value:
                self._syncing = True
                try:
                    self._ik_input.value = True
                finally:
                    self._syncing = False
                self._show_ik_availability()
            self._show(shown, move_target=True)
            return shown

    def pick_solution(self, index: int) -> Reach:
        """Show the closed-form solution ``index`` (``0..m-1``, the ghost labelled
        ``index + 1``) of the current target, as picking it on the page does.

        Raises:
            InputError: the IK mode is off, or no such solution.
        """
        with self._lock:
            shown = self.reach
            if shown is None:
                raise InputError("the IK mode is off: set a target first (set_target)")
            picked = pick(self.subject, shown, index)
            self._show(picked, move_target=False)
            return picked

    # --- collision ------------------------------------------------------------------------------

    @property
    def collision(self) -> CollisionState | None:
        """What the collision view shows at :attr:`q` (:class:`poekin.viewer.collision.
        CollisionState`: the shapes in a penetrating pair, the pairs closer than the margin and
        their witness points), or None while the "collision geometry" box is off."""
        if not self._collision_input.value:
            return None
        return self._collision_state

    @property
    def collision_scene(self) -> CollisionScene | None:
        """The robot's collision geoms and the obstacles drawn
        (:class:`poekin.viewer.collision.CollisionScene`), or None before any is drawn."""
        return self._collision_scene

    def _build_collision_nodes(self, scene: CollisionScene) -> None:
        """A see-through mesh per shape (the robot's collision geoms, hidden while the box is
        off; the obstacles, always shown), posed each update, and the witness points."""
        for k, shape in enumerate(shapes(scene)):
            name = f"/collision/g{k}"
            handle = self.server.scene.add_mesh_simple(
                name,
                shape.vertices,
                shape.faces,
                color=OBSTACLE_COLOR if shape.obstacle else COLLISION_COLOR,
                opacity=OBSTACLE_OPACITY if shape.obstacle else COLLISION_OPACITY,
                side="double" if shape.kind == "plane" else "front",
                cast_shadow=False,
                receive_shadow=False,
                visible=shape.obstacle,
            )
            self._add(name, "obstacle" if shape.obstacle else "collision_geom", handle, k)
        self._build_witness_nodes(scene)

    def _build_witness_nodes(self, scene: CollisionScene) -> None:
        """The witness points as one batched mesh (two small spheres a pair, one slot per
        pair: unused ones at scale 0) and their lines as one set of segments: an update sends
        two messages, however many pairs are near."""
        import trimesh

        e, n = self._extent, max(len(scene.pairs), 1)
        ball = trimesh.creation.icosphere(subdivisions=1, radius=0.014 * e)
        self._add(
            "/collision/witness/points",
            "witness_point",
            self.server.scene.add_batched_meshes_simple(
                "/collision/witness/points",
                np.asarray(ball.vertices, dtype=np.float32),
                np.asarray(ball.faces, dtype=np.uint32),
                batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (2 * n, 1)),
                batched_positions=np.zeros((2 * n, 3)),
                batched_scales=np.zeros(2 * n),
                batched_colors=np.tile(np.array(NEAR_COLOR, dtype=np.uint8), (2 * n, 1)),
                cast_shadow=False,
                receive_shadow=False,
                visible=False,
            ),
        )
        self._add(
            "/collision/witness/lines",
            "witness_line",
            self.server.scene.add_line_segments(
                "/collision/witness/lines",
                np.zeros((n, 2, 3)),
                NEAR_COLOR,
                thickness=0.005 * e,
                visible=False,
            ),
        )

    def _depth_label(self, j: int) -> Any:
        """The ``j``-th depth label (made when first needed): drawn over everything, at a
        penetrating pair, whose witness points lie inside the shapes."""
        name = f"/collision/depth{j}"
        if name not in self._nodes:
            handle = self.server.scene.add_label(name, "", anchor="bottom-left", visible=False)
            self._add(name, "witness_label", handle, j)
        return self._nodes[name].handle

    def _refresh_witness(self, state: CollisionState | None) -> None:
        """The witness points and lines of the pairs closer than the margin (yellow where a
        pair penetrates, orange where it is apart), and a depth label at each penetrating
        pair; nothing with the box off."""
        points = self._nodes["/collision/witness/points"].handle
        lines = self._nodes["/collision/witness/lines"].handle
        k = 0 if state is None else len(state.near)
        _set(points, "visible", k > 0)
        _set(lines, "visible", k > 0)
        deep = 0
        if state is not None and k:
            n = len(lines.points)
            witness, d = state.witness, state.near_distance
            colors = np.where((d < 0)[:, None], WITNESS_COLOR, NEAR_COLOR).astype(np.uint8)
            segments = np.broadcast_to(witness[0, 0], (n, 2, 3)).copy()  # unused: a point
            segments[:k] = witness
            lines.points = segments.astype(np.float32)
            segment_colors = np.broadcast_to(colors[0], (n, 2, 3)).copy()
            segment_colors[:k] = colors[:, None]
            _set(lines, "colors", segment_colors)
            scales = np.zeros(2 * n)
            scales[: 2 * k] = 1.0
            _set(points, "batched_scales", scales)
            points.batched_positions = segments.reshape(2 * n, 3)
            _set(points, "batched_colors", segment_colors.reshape(2 * n, 3))
            for j in np.flatnonzero(d < 0).tolist():
                label = self._depth_label(deep)
                _set(label, "text", f"{d[j] * 1e3:.1f} mm")
                label.position = witness[j].mean(axis=0)
                _set(label, "visible", True)
                deep += 1
        for name in self.node_names("witness_label"):
            if self._nodes[name].index >= deep:
                _set(self._nodes[name].handle, "visible", False)

    def _on_collision_option(self) -> None:
        """The "collision geometry" box or the margin: the robot's collision geoms read (once)
        and shown, or hidden; a model without them says why and the box goes off."""
        if self._syncing:
            return
        with self._lock:
            if self._collision_input.value and self._collision_scene is None:
                try:
                    scene = _collision_scene_of(self.subject, self._obstacles)
                except PoekinError as exc:
                    self._collision_note.content = f"**no collision geometry:** {exc}"
                    self._syncing = True
                    try:
                        self._collision_input.value = False
                    finally:
                        self._syncing = False
                    return
                self._collision_scene = scene
                self._build_collision_nodes(scene)
            self._collision_note.content = ""
            self._refresh()

    def _refresh_collision(self) -> None:
        """The shapes at the configuration shown, red where a pair penetrates, and the witness
        points of the pairs closer than the margin: one query per new configuration."""
        scene = self._collision_scene
        if scene is None:
            return
        on = bool(self._collision_input.value)
        state = None
        if on:
            margin = float(self._margin_input.value) * 1e-3
            state = self._collision_state
            if (
                state is None
                or state.margin != margin
                or not np.array_equal(state.qpos, self._qpos)
            ):
                start = time.perf_counter()
                state = self._collision_state = scene.state(self._qpos, margin)
                self._collision_s = time.perf_counter() - start
            poses = state.poses
        else:
            poses = scene.poses(self._qpos)  # the obstacles on a frame move with it
        for k in range(len(scene.names)):
            name = f"/collision/g{k}"
            handle = self._nodes[name].handle
            obstacle = k >= scene.n_robot
            _set(handle, "visible", on or obstacle)
            if on or obstacle:
                self._pose(name, poses[k])
            red = state is not None and bool(state.colliding[k])
            _set(
                handle,
                "color",
                COLLIDING_COLOR if red else OBSTACLE_COLOR if obstacle else COLLISION_COLOR,
            )
        self._refresh_witness(state)
        if state is None:
            self._texts.pop("collision", None)
            _set(self._collision_text, "content", "")
            return
        self._set_text(
            "collision",
            self._collision_text,
            panel.collision_text(scene, state, query_s=self._collision_s),
        )

    # --- the whole-body IK mode ---------------------------------------------------------------

    @property
    def wholebody(self) -> WholeBodyReach | None:
        """What the whole-body IK mode shows (:class:`poekin.viewer.WholeBodyReach`:
        every handle's target, the configuration, success, each frame's error), or None
        without handles (``view(..., frames=...)``)."""
        return self._wb

    def drag_handle(self, frame: str, T_world_target: ArrayLike) -> WholeBodyReach:
        """Move the whole-body handle on ``frame`` to ``T_world_target`` ``(4, 4)`` and solve
        the whole robot, as a drag of that handle does: every other frame keeps its target,
        the held frames are met exactly; the robot, the sliders and the panel follow.

        Returns:
            What is shown (:attr:`wholebody`): ``success`` False and the best fit where the
            targets are out of reach.

        Raises:
            InputError: no whole-body handles, no handle on ``frame``, a target that is not a
                rigid transform, or held frames that cannot be met together
                (:class:`~poekin.errors.HeldFramesError`); nothing changes.
        """
        with self._lock:
            if self._handles is None or self._wb is None:
                raise InputError(
                    "no whole-body handles: start the viewer with frames=[...] (poekin view "
                    "--ik --frames ...)"
                )
            shown = self._wb_solve(frame, T_world_target)
            self._show_wholebody(shown, move_handles=True)
            return shown

    def _wb_solve(self, frame: str, T: ArrayLike) -> WholeBodyReach:
        assert self.subject.tree is not None and self._wb is not None
        start = time.perf_counter()
        found = wholebody.drag(self.subject.tree, self._wb, frame, T)
        self._wb_solve_s = time.perf_counter() - start
        return found

    def _show_wholebody(self, shown: WholeBodyReach, *, move_handles: bool) -> None:
        """Show ``shown``: its configuration on the robot and the sliders, the handles at its
        targets when ``move_handles`` (a drag has put the dragged one there already)."""
        self._wb = shown
        self._wb_note = ""
        self._qpos = shown.qpos
        if move_handles:
            self._pose_handles(shown)
        self._refresh()
        self._sync_controls()

    def _pose_handles(self, shown: WholeBodyReach) -> None:
        for i, frame in enumerate(shown.handles.frames):
            self._pose(f"/wholebody/h{i}", shown.targets[frame])

    def _check_ik(self) -> None:
        why = self._ik_support.numerical
        if why is not None:
            raise InputError(f"no IK mode for the end frame {self.subject.frame!r}: {why}")

    def _solve(self, T: ArrayLike) -> Reach:
        start = time.perf_counter()
        found = reach(
            self.subject,
            self._qpos,
            T,
            position_only=bool(self._ik_position_input.value),
            ik_support=self._ik_support,
        )
        self._ik_solve_s = time.perf_counter() - start
        return found

    def _show(self, shown: Reach, *, move_target: bool) -> None:
        """Show ``shown``: its configuration on the arm and the sliders, its target (the handle
        moved there when ``move_target``; a drag has put it there already)."""
        if shown.how == "picked":
            self._ik_solve_s = None
        self._reach = shown
        self._qpos = shown.qpos
        if move_target:
            self._pose("/ik/target", shown.target)
        self._refresh()
        self._sync_controls()

    def texts(self) -> dict[str, str]:
        """The panel's readouts as sent to the page: ``pose``, ``jacobian``, ``poe``, ``screws``,
        ``dh``, ``q`` (and ``compare`` with parameters, ``ik`` in the IK mode, ``wholebody``
        with whole-body handles, ``trajectory`` with a trajectory played)."""
        return dict(self._texts)

    def node_names(self, kind: str | None = None) -> list[str]:
        """Names of the scene nodes this viewer made (of one ``kind``: ``body``, ``frame``,
        ``end``, ``home``, ``screw``, ``partial``, ``dh``, ``ghost_link``, ``ghost_screw``,
        ``ghost_end``, ``ghost_home``, ``part``, ``world``; the IK mode's ``ik_target`` (the
        handle), ``ik_marker``, ``ik_miss``, ``solution`` (one batched mesh per part: an
        instance per ghost) and ``solution_label``; the whole-body mode's ``wb_handle``,
        ``wb_marker`` and ``wb_miss``; a trajectory's ``trace`` and ``trace_stop``; the
        collision view's ``collision_geom``, ``obstacle``, ``witness_point``, ``witness_line``
        and ``witness_label``)."""
        return [n for n, node in self._nodes.items() if kind is None or node.kind == kind]

    def node_poses(self, kind: str | None = None) -> dict[str, FloatArray]:
        """World pose ``(4, 4)`` of every scene node (of one ``kind``), composed from the poses
        sent to the page along its parents."""
        out = {}
        for name in self.node_names(kind):
            T = np.eye(4)
            parts = name.strip("/").split("/")
            for depth in range(1, len(parts) + 1):
                node = self._nodes.get("/" + "/".join(parts[:depth]))
                if node is not None:
                    local = np.eye(4)
                    local[:3, :3] = lie.quat_to_rotation(node.handle.wxyz)
                    local[:3, 3] = node.handle.position
                    T = T @ local
            out[name] = T
        return out

    def node(self, name: str) -> Any:
        """The viser handle of a scene node (its ``visible``, ``wxyz``, ``position``, props)."""
        return self._nodes[name].handle

    def close(self) -> None:
        """Stop the server (the page shows it as disconnected)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._clock is not None:
                self._clock.playing = False
            with contextlib.redirect_stdout(io.StringIO()):  # viser says "Server stopped"
                self.server.stop()
        # let a mesh compile in progress finish: native code running in a daemon thread while
        # the interpreter shuts down can crash it
        for thread in (getattr(self, "_loader", None), getattr(self, "_player", None)):
            if thread is not None and thread is not threading.current_thread():
                thread.join(timeout=60.0)

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Viewer({self.subject.name!r}, frame={self.frame!r}, url={self.url!r})"

    def _repr_html_(self) -> str:
        """In Jupyter: the live page inline."""
        return (
            f'<iframe src="{self.url}" width="100%" height="600" '
            'style="border:1px solid #ddd"></iframe>'
        )

    # --- scene --------------------------------------------------------------------------------

    def _add(self, name: str, kind: str, handle: Any, index: int = -1) -> Any:
        self._nodes[name] = _Node(handle, kind, index)
        return handle

    def _triad(
        self,
        name: str,
        kind: str,
        *,
        scale: float = 1.0,
        label: str | None = None,
        visible: bool = True,
        index: int = -1,
        below: bool = False,
    ) -> Any:
        e = self._extent
        handle = self.server.scene.add_frame(
            name,
            axes_length=0.09 * e * scale,
            axes_radius=0.004 * e * scale,
            origin_radius=0.008 * e * scale,
            visible=visible,
        )
        self._add(name, kind, handle, index)
        if label is not None:
            self._add(
                f"{name}/label",
                "label",
                self.server.scene.add_label(
                    f"{name}/label",
                    label,
                    position=(0.0, 0.0, (-0.02 if below else 0.03) * e * scale),
                    anchor="top-right" if below else "bottom-left",
                ),
            )
        return handle

    def _build_scene(self) -> None:
        scene, e, subject = self.server.scene, self._extent, self.subject
        scene.set_up_direction("+z")
        cell = 10.0 ** math.floor(math.log10(e / 2))
        scene.add_grid(
            "/grid",
            width=4 * e,
            height=4 * e,
            cell_size=cell,
            section_size=10 * cell,
            shadow_opacity=0.0,
        )
        self._triad("/world", "world", scale=1.3, label="world")
        for b in range(len(subject.body_names)):
            self._add(f"/robot/b{b}", "body", scene.add_frame(f"/robot/b{b}", show_axes=False), b)
        for f, name in enumerate(subject.frame_names):
            self._triad(f"/frames/f{f}", "frame", scale=0.6, label=name, visible=False, index=f)
        self._triad("/home", "home", scale=0.8, label="M (home)", below=True)
        self._build_chain_nodes()
        if self.comparison is not None:
            self._build_ghost_nodes()
        self._build_ik_nodes()
        if self._handles is not None:
            self._build_wholebody_nodes()
        if self._playback is not None:
            self._build_play_nodes()
        if self._collision_scene is not None:
            self._build_collision_nodes(self._collision_scene)
        position, look_at = self._camera(snapshot(subject, self._qpos))
        self.server.initial_camera.position = position
        self.server.initial_camera.look_at = look_at

    def _camera(self, snap: Snapshot) -> tuple[FloatArray, FloatArray]:
        """A camera position and target that show the robot (and your arm) at ``snap``, left
        of centre: the panel covers the right third of the page."""
        origins = np.vstack([snap.frames[:, :3, 3], snap.points, snap.T[None, :3, 3]])
        if self.comparison is not None:  # your arm too: as given, it may point elsewhere
            gh = ghost(self.comparison, snap, aligned=self._aligned)
            origins = np.vstack([origins, gh.points, gh.T[None, :3, 3]])
        shown = self._reach  # None while the page is built
        if shown is not None and self._ik_input.value:  # the IK target and the ghosts
            _, anchors = ghost_poses(self.subject, shown.solutions[shown.ghosts])
            origins = np.vstack([origins, shown.target[None, :3, 3], *anchors])
        if self._wb is not None:  # the whole-body handles' targets
            origins = np.vstack([origins, *(T[None, :3, 3] for T in self._wb.targets.values())])
        lo, hi = origins.min(axis=0), origins.max(axis=0)
        centre, size = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)), 0.1)
        position = centre + size * np.array([0.52, -0.72, 0.4])  # fills the view left of it
        forward = (centre - position) / np.linalg.norm(centre - position)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        return position, centre + 0.3 * size * right / np.linalg.norm(right)

    def frame_view(self) -> None:
        """Point every open page's camera at the robot as it is now (the button "frame the
        robot" does it for one page)."""
        position, look_at = self._camera(self.snapshot())
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.position = position
                client.camera.look_at = look_at

    def _screw_node(
        self,
        name: str,
        kind: str,
        index: int,
        screw: FloatArray,
        color: tuple[int, int, int],
        label: str,
    ) -> None:
        """A screw axis at the origin along z: the line through its axis point with an arrow,
        a curved arrow for the positive turn (a helix for a pitched screw), a rail of ticks
        for a prismatic one; posed each update."""
        scene, e = self.server.scene, self._extent
        L = 0.25 * e
        self._add(name, kind, scene.add_frame(name, show_axes=False), index)
        what = screw_kind(screw)
        start = 0.0 if what == "prismatic" else -0.6 * L
        self._add(
            f"{name}/arrow",
            "arrow",
            scene.add_arrows(
                f"{name}/arrow",
                np.array([[[0.0, 0.0, start], [0.0, 0.0, L]]]),
                color,
                shaft_radius=0.005 * e,
                head_radius=0.014 * e,
                head_length=0.04 * e,
            ),
        )
        segments = _turn_marker(what, float(screw[:3] @ screw[3:]) if what == "pitched" else 0.0, e)
        self._add(
            f"{name}/turn",
            "turn",
            scene.add_line_segments(f"{name}/turn", segments, color, thickness=0.003 * e),
        )
        self._add(
            f"{name}/label",
            "label",
            scene.add_label(
                f"{name}/label", label, position=(0.0, 0.0, 1.12 * L), anchor="bottom-center"
            ),
        )

    def _build_chain_nodes(self) -> None:
        """Nodes that depend on the end frame: screws, end frame, PoE steps, DH frames."""
        scene, e, subject = self.server.scene, self._extent, self.subject
        snap = snapshot(subject, self._qpos)
        for i in range(subject.n_joints):
            self._screw_node(f"/screws/s{i}", "screw", i, snap.screws[i], MODEL_COLOR, f"S{i + 1}")
        self._add(
            "/levers",
            "levers",
            scene.add_line_segments(
                "/levers",
                np.zeros((max(subject.n_joints, 1), 2, 3)),
                LEVER_COLOR,
                thickness=0.002 * e,
                visible=False,
            ),
        )
        self._triad("/end", "end", scale=1.25, label=f"T(q): {subject.end_name}")
        for k in range(subject.n_joints + 1):
            self._triad(f"/poe/t{k}", "partial", scale=0.7, visible=False, index=k)
        self._add(
            "/poe/label",
            "label",
            scene.add_label("/poe/label", "T", anchor="top-left", visible=False),
        )
        self._add(
            "/poe/path",
            "poe_path",
            scene.add_line_segments(
                "/poe/path",
                np.zeros((max(subject.n_joints, 1), 2, 3)),
                PARTIAL_COLOR,
                thickness=0.003 * e,
                visible=False,
            ),
        )
        for i in range(subject.n_joints + 2):
            label = f"DH {i}" if i <= subject.n_joints else "DH tool"
            self._triad(f"/dh/f{i}", "dh", scale=0.7, label=label, visible=False, index=i)

    def _remove_chain_nodes(self) -> None:
        """Remove what :meth:`_build_chain_nodes` made (a node's children go with it)."""
        doomed = [
            n for n in self._nodes if n.split("/")[1] in ("screws", "levers", "end", "poe", "dh")
        ]
        for name in doomed:
            node = self._nodes.pop(name)
            if name.rsplit("/", 1)[0] not in doomed:
                node.handle.remove()

    def _build_ghost_nodes(self) -> None:
        assert self.comparison is not None
        scene, e = self.server.scene, self._extent
        labels = self.comparison.diagnosis.joint_labels()
        chain = self.comparison.chain(self._aligned)
        n = chain.n_joints
        self._add(
            "/ghost/arm",
            "ghost_arm",
            scene.add_line_segments(
                "/ghost/arm", np.zeros((n + 1, 2, 3)), YOURS_COLOR, thickness=0.012 * e
            ),
        )
        for i in range(n):
            bad = i in labels
            label = f"J{i + 1} {labels[i]}" if bad else ""
            self._screw_node(
                f"/ghost/s{i}",
                "ghost_screw",
                i,
                chain.screws[i],
                MISMATCH_COLOR if bad else YOURS_COLOR,
                label,
            )
        self._triad("/ghost/end", "ghost_end", scale=1.1, label=f"yours: {self.comparison.name}")
        self._triad("/ghost/home", "ghost_home", scale=0.7, label="your M")

    def _build_ik_nodes(self) -> None:
        """The IK mode's target handle (a transform control, dragged on the page) with its
        marker and label, and the line from the end frame to a target out of reach."""
        scene, e = self.server.scene, self._extent
        handle = self._add(
            "/ik/target",
            "ik_target",
            scene.add_transform_controls(
                "/ik/target", scale=0.3 * e, line_width=3.0, depth_test=False, visible=False
            ),
        )
        handle.on_update(lambda _: self._on_target_drag())
        self._add(
            "/ik/target/marker",
            "ik_marker",
            scene.add_icosphere(
                "/ik/target/marker", radius=0.025 * e, color=TARGET_COLOR, visible=False
            ),
        )
        self._add(
            "/ik/target/label",
            "label",
            scene.add_label(
                "/ik/target/label",
                "IK target",
                position=(0.0, 0.0, -0.04 * e),
                anchor="top-left",
                visible=False,
            ),
        )
        self._add(
            "/ik/miss",
            "ik_miss",
            scene.add_line_segments(
                "/ik/miss",
                np.zeros((1, 2, 3)),
                UNREACHABLE_COLOR,
                thickness=0.004 * e,
                visible=False,
            ),
        )

    def _build_wholebody_nodes(self) -> None:
        """A transform control on each whole-body frame (dragged on the page), with a marker
        and a label (its name, held or not), and the lines from the frames to the targets they
        miss."""
        assert self._handles is not None
        scene, e = self.server.scene, self._extent
        for i, frame in enumerate(self._handles.frames):
            name = f"/wholebody/h{i}"
            handle = self._add(
                name,
                "wb_handle",
                scene.add_transform_controls(
                    name, scale=0.16 * e, line_width=2.5, depth_test=False
                ),
                i,
            )
            handle.on_update(lambda _, i=i: self._on_handle_drag(i))
            held = frame in self._handles.hold
            self._add(
                f"{name}/marker",
                "wb_marker",
                scene.add_icosphere(
                    f"{name}/marker",
                    radius=0.018 * e,
                    color=HELD_COLOR if held else TARGET_COLOR,
                ),
                i,
            )
            self._add(
                f"{name}/label",
                "label",
                scene.add_label(
                    f"{name}/label",
                    f"{frame} (held)" if held else frame,
                    position=(0.0, 0.0, -0.03 * e),
                    anchor="top-left",
                ),
            )
        self._add(
            "/wholebody/miss",
            "wb_miss",
            scene.add_line_segments(
                "/wholebody/miss",
                np.zeros((len(self._handles.frames), 2, 3)),
                UNREACHABLE_COLOR,
                thickness=0.004 * e,
                visible=False,
            ),
        )

    def _build_play_nodes(self) -> None:
        """The tool trace of the trajectory played (the end frame's positions at every sample,
        as line segments) and, where its path stopped early, a marker with the reason."""
        assert self._playback is not None
        scene, e = self.server.scene, self._extent
        self._add(
            "/play/trace",
            "trace",
            scene.add_line_segments(
                "/play/trace", self._trace_segments(), TRACE_COLOR, thickness=0.004 * e
            ),
        )
        trajectory = self._playback.trajectory
        stop = trajectory.stop_time
        if stop is None:
            return
        at = self._playback.index(stop)
        self._add(
            "/play/stop",
            "trace_stop",
            scene.add_icosphere(
                "/play/stop",
                radius=0.012 * e,
                color=STOP_COLOR,
                position=self._trace_points()[at],
            ),
        )
        self._add(
            "/play/stop/label",
            "label",
            scene.add_label(
                "/play/stop/label",
                trajectory.stop_words(),
                position=(0.0, 0.0, 0.03 * e),
                anchor="bottom-left",
            ),
        )

    def _trace_points(self) -> FloatArray:
        assert self._playback is not None
        return tool_trace(self.subject, self._playback.qpos)

    def _trace_segments(self) -> NDArray[np.float32]:
        """``(K - 1, 2, 3)`` the trace's segments, from each sample to the next."""
        p = self._trace_points()
        return np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)

    def _build_solution_meshes(self, geometry: Geometry) -> None:
        """One batched mesh per part of the robot, an instance per ghost solution (posed by its
        body's pose in that solution), clickable; sent once, when the IK mode first shows
        ghosts."""
        for k, part in enumerate(geometry.parts):
            name = f"/ik/solutions/part{k}"
            handle = self.server.scene.add_batched_meshes_simple(
                name,
                part.vertices,
                part.faces,
                batched_wxyzs=np.array([[1.0, 0.0, 0.0, 0.0]]),
                batched_positions=np.zeros((1, 3)),
                batched_colors=SOLUTION_COLOR,
                opacity=SOLUTION_OPACITY,
                cast_shadow=False,
                receive_shadow=False,
                visible=False,
            )
            handle.on_click(lambda event: self._on_ghost_click(event.instance_index))
            self._add(name, "solution", handle, part.body)
        self._solution_meshes = True

    def _solution_label(self, j: int) -> Any:
        """The ``j``-th label of the ghost solutions (made when first needed)."""
        name = f"/ik/solutions/label{j}"
        if name not in self._nodes:
            self._add(
                name,
                "solution_label",
                self.server.scene.add_label(name, "", anchor="bottom-center", visible=False),
                j,
            )
        return self._nodes[name].handle

    def _load_geometry(self) -> None:
        try:
            geometry = self._geometry_fn(self.subject)
        except Exception as exc:  # a broken mesh file must not take the viewer down
            geometry = stand_in(self.subject, f"the geometry failed to load: {exc}")
        with self._lock:
            if self._closed:
                return
            with self.server.atomic():
                for k, part in enumerate(geometry.parts):
                    self._add_part(k, part)
                self._geometry = geometry
                self._geometry_note.content = f"geometry: {geometry.note}"
                if self._ik_input.value:  # the ghost solutions can be drawn now
                    self._refresh()
        self._geometry_ready.set()

    def _add_part(self, k: int, part: Part) -> None:
        name = f"/robot/b{part.body}/part{k}"
        handle = self.server.scene.add_mesh_simple(
            name,
            part.vertices,
            part.faces,
            color=part.color,
            visible=self._show_geometry.value,
        )
        self._nodes[name] = _Node(handle, "part", part.body, part.opacity)
        handle.opacity = self._part_opacity(name)

    # --- panel --------------------------------------------------------------------------------

    def _build_gui(self, collision: bool) -> None:
        gui, subject = self.server.gui, self.subject
        gui.configure_theme(control_width="large", show_share_button=False)
        title = f"**{subject.name}**, end frame `{subject.end_name}`, {subject.n_joints} joints"
        if subject.base_body is not None and subject.tree is not None:
            title += f" from the floating body `{subject.tree.body_names[subject.base_body]}`"
        self._title = gui.add_markdown(title)
        self._geometry_note = gui.add_markdown("geometry: loading ...")
        frame_button = gui.add_button("frame the robot", hint="point the camera at the robot")
        frame_button.on_click(lambda event: self._frame_client(event.client))
        if subject.tree is not None and self.comparison is None:
            self._frame_input: Any = gui.add_dropdown(
                "end frame", list(subject.tree.frame_names), initial_value=subject.frame
            )
            self._frame_input.on_update(lambda _: self._on_frame())
        if self._handles is not None:
            with gui.add_folder("Whole-body IK"):
                self._wb_text = gui.add_markdown("")
        if self._playback is not None:
            with gui.add_folder("Trajectory"):
                self._build_play_controls()
        with gui.add_folder("Inverse kinematics"):
            self._build_ik_controls()
        with gui.add_folder("Collision"):
            self._build_collision_controls(collision)
        tabs = gui.add_tab_group()
        with tabs.add_tab("Joints"):
            self._build_joint_controls()
        with tabs.add_tab("Screws & PoE"):
            self._form_input: Any = gui.add_dropdown(
                "form", ["space (S_i)", "body (B_i)"], initial_value="space (S_i)"
            )
            self._form_input.on_update(lambda _: self._on_view_option())
            self._step_input: Any = gui.add_slider(
                "PoE step k", 0, max(subject.n_joints, 1), 1, subject.n_joints
            )
            self._step_input.on_update(lambda _: self._on_view_option())
            self._poe_text = gui.add_markdown("")
            self._show_screws: Any = gui.add_checkbox("screw axes", True)
            self._show_levers: Any = gui.add_checkbox(
                "moment arms (v = -w x r)",
                False,
                hint="from the frame of the form to the nearest point of each axis",
            )
            self._show_home: Any = gui.add_checkbox("home pose M", True)
            self._show_frames: Any = gui.add_checkbox("all frames", False)
            self._show_geometry: Any = gui.add_checkbox("robot geometry", True)
            self._opacity_input: Any = gui.add_slider("robot opacity", 0.1, 1.0, 0.05, 0.6)
            self._opacity_input.on_update(lambda _: self._on_opacity())
            for box in (
                self._show_screws,
                self._show_levers,
                self._show_home,
                self._show_frames,
                self._show_geometry,
            ):
                box.on_update(lambda _: self._on_view_option())
            self._screws_text = gui.add_markdown("")
        with tabs.add_tab("T(q) & J"):
            self._pose_text = gui.add_markdown("")
            self._convention_input: Any = gui.add_dropdown(
                "Jacobian", ["space", "body", "world"], initial_value="space"
            )
            self._convention_input.on_update(lambda _: self._on_view_option())
            self._jacobian_text = gui.add_markdown("")
        with tabs.add_tab("DH"):
            self._show_dh: Any = gui.add_checkbox("DH frames", False)
            self._dh_input: Any = gui.add_dropdown(
                "convention", ["standard", "modified"], initial_value="standard"
            )
            for handle in (self._show_dh, self._dh_input):
                handle.on_update(lambda _: self._on_view_option())
            self._dh_text = gui.add_markdown("")
        if self.comparison is not None:
            with tabs.add_tab("Compare"):
                self._align_input: Any = gui.add_checkbox("align your base to the model's", False)
                self._align_input.on_update(lambda _: self._on_align())
                self._compare_text = gui.add_markdown("")
        self._options: dict[str, Any] = {
            handle.label: handle
            for handle in (
                self._unit_input,
                self._form_input,
                self._step_input,
                self._show_screws,
                self._show_levers,
                self._show_home,
                self._show_frames,
                self._show_geometry,
                self._opacity_input,
                self._convention_input,
                self._show_dh,
                self._dh_input,
                self._ik_input,
                self._ik_position_input,
                self._show_solutions_input,
                self._collision_input,
                self._margin_input,
                *([self._frame_input] if hasattr(self, "_frame_input") else []),
                *([self._time_input, self._trace_input] if self._playback is not None else []),
                *([self._align_input] if self.comparison is not None else []),
            )
        }

    def _build_play_controls(self) -> None:
        """The trajectory's time slider (s), its play/pause button, the trace's check box and
        what it is."""
        assert self._playback is not None
        gui, shown = self.server.gui, self._playback
        text = panel.trajectory_text(shown.trajectory, shown.what)
        self._texts["trajectory"] = text
        self._play_text = gui.add_markdown(text)
        step = float(np.min(np.diff(shown.t)))
        self._time_input: Any = gui.add_slider(
            "time [s]", shown.start, shown.end, step, shown.start
        )
        self._time_input.on_update(lambda _: self._on_time())
        self._play_button = gui.add_button("play", hint="play the trajectory in real time")
        self._play_button.on_click(lambda _: self.pause() if self.playing else self.play())
        self._trace_input: Any = gui.add_checkbox(
            "tool trace", True, hint="the end frame's path over the whole trajectory"
        )
        self._trace_input.on_update(lambda _: self._on_view_option())

    def _build_collision_controls(self, on: bool) -> None:
        """The "collision geometry" box (disabled for a bare parameter set, which has none),
        the witness points' margin (mm) and what collides."""
        gui = self.server.gui
        self._collision_input: Any = gui.add_checkbox(
            "collision geometry",
            on,
            disabled=self.subject.tree is None,
            hint="the model's collision geoms (meshes as their convex hulls), red where a pair "
            "penetrates, with the witness points of the pairs closer than the margin",
        )
        self._margin_input: Any = gui.add_slider(
            "collision margin [mm]", 0.0, _MARGIN_MAX_MM, 1.0, DEFAULT_MARGIN * 1e3
        )
        for handle in (self._collision_input, self._margin_input):
            handle.on_update(lambda _: self._on_collision_option())
        self._collision_note = gui.add_markdown(
            ""
            if self.subject.tree is not None
            else "a bare parameter set has no collision geometry: show a model"
        )
        self._collision_text = gui.add_markdown("")

    def _build_ik_controls(self) -> None:
        gui = self.server.gui
        self._ik_input: Any = gui.add_checkbox(
            "IK target",
            False,
            hint="a target handle at the end frame: drag it and the arm follows (inverse "
            "kinematics from the configuration shown)",
        )
        self._ik_input.on_update(lambda _: self._on_ik_option())
        self._ik_position_input: Any = gui.add_checkbox(
            "position only",
            self.subject.n_joints < 6,
            hint="reach the target's position whatever the orientation (arms with fewer than "
            "six joints, legs)",
        )
        self._ik_position_input.on_update(lambda _: self._on_ik_option())
        self._show_solutions_input: Any = gui.add_checkbox(
            "ghost solutions",
            True,
            hint="the other closed-form solutions as ghost arms, numbered as in the picker",
        )
        self._show_solutions_input.on_update(lambda _: self._on_view_option())
        self._ik_note = gui.add_markdown("")
        self._ik_text = gui.add_markdown("")
        self._solution_input: Any = gui.add_dropdown(
            "solution", [_NO_SOLUTION], hint="the closed-form solutions; the number is the ghost's"
        )
        self._solution_input.on_update(lambda _: self._on_solution_choice())
        self._target_input: Any = gui.add_text(
            "target", "", hint="x y z qw qx qy qz: metres, a unit quaternion, world frame"
        )
        self._target_button = gui.add_button("set target")
        self._target_button.on_click(lambda _: self._on_set_target())
        self._ik_rows = (
            self._ik_position_input,
            self._show_solutions_input,
            self._ik_text,
            self._solution_input,
            self._target_input,
            self._target_button,
        )
        self._show_ik_availability()

    def _show_ik_availability(self) -> None:
        """Enable the IK mode's check box for an end frame it applies to; else disable it and
        say why."""
        why = self._ik_support.numerical
        self._ik_input.disabled = why is not None
        self._ik_note.content = "" if why is None else f"IK mode: not for this frame: {why}"
        on = bool(self._ik_input.value)
        for row in self._ik_rows:
            row.visible = on
        closed_form = on and self._ik_support.analytic is None and not self._ik_position_input.value
        self._solution_input.visible = self._show_solutions_input.visible = closed_form

    def _build_joint_controls(self) -> None:
        gui = self.server.gui
        self._unit_input: Any = gui.add_dropdown("angles", ["rad", "deg"], initial_value="rad")
        self._unit_input.on_update(lambda _: self._on_unit())
        self._sliders: list[tuple[Control, str, Any]] = []
        e = self._extent
        for c in self._controls:
            if c.kind in ("revolute", "prismatic"):
                step = _REVOLUTE_STEP if c.kind == "revolute" else _SLIDE_STEP
                start_value = float(np.clip(self._qpos[c.adr], c.lower, c.upper))
                slider = gui.add_slider(c.joint, c.lower, c.upper, step, start_value)
                self._sliders.append((c, "value", slider))
                continue
            start = c.adr
            if c.kind == "free":
                for axis, key in enumerate("xyz"):
                    x0 = float(self._qpos[start + axis])
                    lo, hi = min(x0 - 2 * e, -2 * e), max(x0 + 2 * e, 2 * e)
                    slider = gui.add_slider(f"{c.joint} {key} [m]", lo, hi, _SLIDE_STEP, x0)
                    self._sliders.append((c, key, slider))
            for key in ("roll", "pitch", "yaw"):
                lim = math.pi / 2 if key == "pitch" else math.pi
                slider = gui.add_slider(f"{c.joint} {key}", -lim, lim, _REVOLUTE_STEP, 0.0)
                self._sliders.append((c, key, slider))
        for control, _key, slider in self._sliders:
            slider.on_update(lambda _, c=control: self._on_slider(c))
        self._zero_button = gui.add_button(
            "zero", hint="every hinge and slide at 0, ball joints at the identity"
        )
        self._random_button = gui.add_button(
            "random", hint="hinges and slides uniform within their slider range"
        )
        home = "home" if "home" in self.subject.keyframes else None
        self._home_button = gui.add_button(
            "home" + (" (keyframe 'home')" if home else " (qpos0)"),
            hint="the model's keyframe 'home'"
            if home
            else "the model's default configuration qpos0",
        )
        self._zero_button.on_click(lambda _: self._on_button("zero"))
        self._random_button.on_click(lambda _: self._on_button("random"))
        self._home_button.on_click(lambda _: self._on_button("home"))
        self._q_input: Any = gui.add_text(
            "qpos", "", hint="all values, rad and m, MuJoCo's qpos layout; then 'set qpos'"
        )
        self._q_button = gui.add_button("set qpos")
        self._q_button.on_click(lambda _: self._on_set_q())
        self._q_note = gui.add_markdown("")

    # --- events ---------------------------------------------------------------------------------

    def _slider_value(self, kind: str, value: float) -> float:
        """A hinge slider's value in radians (it shows degrees in degree mode)."""
        return (
            math.radians(value)
            if kind in ("revolute", "roll", "pitch", "yaw") and self._unit == "deg"
            else value
        )

    def _on_slider(self, c: Control) -> None:
        if self._syncing:
            return
        with self._lock:
            x = self._qpos.copy()
            mine = {key: slider.value for control, key, slider in self._sliders if control is c}
            if c.kind in ("revolute", "prismatic"):
                x[c.adr] = self._slider_value(c.kind, float(mine["value"]))
            else:
                start = c.adr
                if c.kind == "free":
                    x[start : start + 3] = [float(mine[k]) for k in "xyz"]
                    start += 3
                rpy = [self._slider_value("roll", float(mine[k])) for k in ("roll", "pitch", "yaw")]
                x[start : start + 4] = _quat(_rpy_rotation(*rpy))
            self._qpos = x
            self._refresh()

    def _on_button(self, which: str) -> None:
        x = self._qpos.copy()
        for c in self._controls:
            if which == "home":
                x = self.subject.keyframes.get("home", self.subject.qpos0).copy()
                break
            if c.kind in ("revolute", "prismatic"):
                x[c.adr] = 0.0 if which == "zero" else self._rng.uniform(c.lower, c.upper)
            elif c.kind == "ball":
                quat = [1.0, 0.0, 0.0, 0.0] if which == "zero" else self._rng.normal(size=4)
                x[c.adr : c.adr + 4] = np.asarray(quat) / np.linalg.norm(quat)
        self.q = x

    def _on_set_q(self) -> None:
        text = self._q_input.value.replace(",", " ").replace("[", " ").replace("]", " ")
        try:
            self.q = [float(t) for t in text.split()]
        except (ValueError, InputError) as exc:
            self._q_note.content = f"**not set:** {exc}"
            return
        self._q_note.content = ""

    def _on_unit(self) -> None:
        unit: Unit = "deg" if self._unit_input.value == "deg" else "rad"
        with self._lock:
            self._unit = unit
            self._syncing = True
            try:
                for c, key, slider in self._sliders:
                    if c.kind == "revolute" or key in ("roll", "pitch", "yaw"):
                        f = math.degrees if unit == "deg" else (lambda v: v)
                        lo, hi = (
                            (c.lower, c.upper)
                            if c.kind == "revolute"
                            else (
                                (-math.pi / 2, math.pi / 2)
                                if key == "pitch"
                                else (-math.pi, math.pi)
                            )
                        )
                        slider.step = _DEGREE_STEP if unit == "deg" else _REVOLUTE_STEP
                        slider.min, slider.max = f(lo), f(hi)
            finally:
                self._syncing = False
            self._sync_controls()
            self._refresh()

    def _on_view_option(self) -> None:
        if self._syncing:
            return
        with self._lock:
            self._form = "body" if self._form_input.value.startswith("body") else "space"
            self._k = int(self._step_input.value)
            self._convention = self._convention_input.value  # type: ignore[assignment]
            self._dh_convention = self._dh_input.value  # type: ignore[assignment]
            symbol = _SYMBOL[self._form]
            for i in range(self.subject.n_joints):
                self._nodes[f"/screws/s{i}/label"].handle.text = f"{symbol}{i + 1}"
            if self._playback is not None:
                _set(self._nodes["/play/trace"].handle, "visible", bool(self._trace_input.value))
            self._refresh()

    def _on_ik_option(self) -> None:
        """The IK check box or "position only": the target starts at the end frame, or is
        solved again for the other kind of target."""
        if self._syncing:
            return
        with self._lock:
            if self._ik_input.value and self._ik_support.numerical is not None:
                self._syncing = True
                try:
                    self._ik_input.value = False  # a disabled box: refused
                finally:
                    self._syncing = False
            shown = self._reach
            self._show_ik_availability()
            if self._ik_input.value and shown is not None and shown.how != "follow":
                self._show(self._solve(shown.target), move_target=False)
                return
            self._reach = None  # on: the target at the end frame
            self._refresh()

    def _on_target_drag(self) -> None:
        """A drag of the target handle (each pose the page sends, in viser's thread pool):
        solve for the handle's pose as it is now, the latest one."""
        with self._lock:
            if self._closed or not self._ik_input.value:
                return
            handle = self._nodes["/ik/target"].handle
            T = np.eye(4)
            T[:3, :3] = lie.quat_to_rotation(lie.quat_normalize(handle.wxyz))
            T[:3, 3] = handle.position
            if self._reach is not None and np.array_equal(T, self._reach.target):
                return  # an update already solved
            self._show(self._solve(T), move_target=False)

    def _on_handle_drag(self, i: int) -> None:
        """A drag of whole-body handle ``i`` (each pose the page sends, in viser's thread
        pool): solve the whole robot for the handle's pose as it is now, the latest one. Held
        frames that cannot be met together: the handle goes back, the panel says why."""
        with self._lock:
            shown = self._wb
            if self._closed or shown is None:
                return
            frame = shown.handles.frames[i]
            handle = self._nodes[f"/wholebody/h{i}"].handle
            T = np.eye(4)
            T[:3, :3] = lie.quat_to_rotation(lie.quat_normalize(handle.wxyz))
            T[:3, 3] = handle.position
            if np.array_equal(T, shown.targets[frame]):
                return  # an update already solved
            try:
                found = self._wb_solve(frame, T)
            except InputError as exc:
                self._pose(f"/wholebody/h{i}", shown.targets[frame])
                self._wb_note = f"**{frame} not moved:** {exc}"
                self._refresh()
                return
            self._show_wholebody(found, move_handles=False)

    def _on_set_target(self) -> None:
        try:
            T = _pose_from_text(self._target_input.value)
            self.set_target(T)
        except InputError as exc:
            self._ik_note.content = f"**target not set:** {exc}"
            return
        self._ik_note.content = ""

    def _on_solution_choice(self) -> None:
        if self._syncing:
            return
        choice = self._solution_input.value
        if choice != _NO_SOLUTION:
            with self._lock:
                if self.reach is not None:
                    self.pick_solution(int(choice.split(":")[0]) - 1)

    def _on_ghost_click(self, instance: int | None) -> None:
        """A click on a ghost: show its solution. The instances are the ghosts in the order
        of :attr:`Reach.ghosts <poekin.viewer.ik.Reach.ghosts>`."""
        with self._lock:
            shown = self.reach
            if shown is not None and instance is not None and 0 <= instance < len(shown.ghosts):
                self.pick_solution(shown.ghosts[instance])

    def _frame_client(self, client: Any) -> None:
        if client is None:
            return
        position, look_at = self._camera(self.snapshot())
        with client.atomic():
            client.camera.position = position
            client.camera.look_at = look_at

    def _on_opacity(self) -> None:
        with self._lock:
            for name in self.node_names("part"):
                self._nodes[name].handle.opacity = self._part_opacity(name)

    def _part_opacity(self, name: str) -> float | None:
        """A part's opacity: its own (from the model) times the slider's; None is opaque."""
        value = self._opacity_input.value * self._nodes[name].opacity
        return None if value >= 1.0 else float(value)

    def _on_align(self) -> None:
        with self._lock:
            self._aligned = bool(self._align_input.value)
            self._refresh()

    def _on_frame(self) -> None:
        frame = self._frame_input.value
        if frame == self.subject.frame:
            return
        with self._lock:
            subject = self.subject
            assert subject.tree is not None
            try:
                tool_frame, tool = self._tool_on
                new = make_subject(
                    subject.tree,
                    frame,
                    keyframes=subject.keyframes,
                    name=subject.name,
                    tool=tool if frame == tool_frame else None,
                )  # type: ignore[arg-type]
            except Exception as exc:
                self._q_note.content = f"**cannot show {frame!r}:** {exc}"
                return
            with self.server.atomic():
                self._remove_chain_nodes()
                self.subject = new
                self._build_chain_nodes()
                self._syncing = True
                try:
                    self._step_input.max = max(new.n_joints, 1)
                    self._step_input.value = new.n_joints
                finally:
                    self._syncing = False
                self._k = new.n_joints
                self._ik_support = support(new)
                self._reach = None  # the IK target: at the new end frame
                self._syncing = True
                try:
                    self._ik_position_input.value = new.n_joints < 6
                    if not self._ik_support.available:
                        self._ik_input.value = False
                finally:
                    self._syncing = False
                self._show_ik_availability()
                title = f"**{new.name}**, end frame `{new.end_name}`, {new.n_joints} joints"
                if new.base_body is not None and new.tree is not None:
                    title += f" from the floating body `{new.tree.body_names[new.base_body]}`"
                self._title.content = title
                if self._playback is not None:
                    self._refresh_trace()
                self._on_view_option()

    def _sync_controls(self) -> None:
        """Show the current configuration on the sliders and in the qpos box, without
        treating that as input."""
        self._syncing = True
        try:
            x = self._qpos
            for c, key, slider in self._sliders:
                deg = self._unit == "deg"
                if key == "value":
                    value = float(x[c.adr])
                    value = math.degrees(value) if deg and c.kind == "revolute" else value
                elif key in "xyz":
                    value = float(x[c.adr + "xyz".index(key)])
                else:
                    start = c.adr + (3 if c.kind == "free" else 0)
                    quat = np.asarray(lie.quat_normalize(x[start : start + 4]), dtype=np.float64)
                    rpy = lie.rotation_to_rpy(lie.quat_to_rotation(quat))
                    value = float(rpy[("roll", "pitch", "yaw").index(key)])
                    value = math.degrees(value) if deg else value
                slider.value = value
            self._q_input.value = " ".join(f"{v + 0.0:.6g}" for v in x)
        finally:
            self._syncing = False

    # --- one update -------------------------------------------------------------------------------

    def _pose(self, name: str, T: FloatArray) -> None:
        """Queue a node's world pose; :meth:`_send_poses` sends them all at once."""
        self._pending.append((name, T))

    def _send_poses(self) -> None:
        """Set the queued poses: one batched quaternion conversion, then each node's pose."""
        if not self._pending:
            return
        names = [name for name, _ in self._pending]
        T = np.stack([T for _, T in self._pending])
        quats = np.asarray(lie.rotation_to_quat(T[:, :3, :3]), dtype=np.float64)
        self._pending = []
        for name, quat, p in zip(names, quats, T[:, :3, 3], strict=True):
            handle = self._nodes[name].handle
            handle.wxyz = quat
            handle.position = p

    def _set_text(self, key: str, handle: Any, text: str) -> None:
        if self._texts.get(key) != text:
            self._texts[key] = text
            handle.content = text

    def _refresh(self) -> None:
        """Pose every node and write every readout for the current configuration."""
        subject, snap = self.subject, snapshot(self.subject, self._qpos)
        with self.server.atomic():
            for b, T in enumerate(snap.bodies):
                self._pose(f"/robot/b{b}", T)
            show_frames = self._show_frames.value
            for f, T in enumerate(snap.frames):
                node = self._nodes[f"/frames/f{f}"].handle
                node.visible = show_frames
                if show_frames:
                    self._pose(f"/frames/f{f}", T)
            for node in self.node_names("part"):
                self._nodes[node].handle.visible = self._show_geometry.value
            self._pose("/end", snap.T)
            self._pose("/home", snap.home)
            self._nodes["/home"].handle.visible = self._show_home.value
            self._nodes["/home/label"].handle.visible = self._show_home.value
            self._refresh_screws(snap)
            self._refresh_poe(snap)
            self._refresh_dh()
            J, columns = jacobian(subject, snap.qpos, self._convention)
            sigma, w = manipulability(J)
            self._set_text("pose", self._pose_text, panel.pose_text(snap.T, subject.chain.frame))
            self._set_text(
                "jacobian",
                self._jacobian_text,
                panel.jacobian_text(J, columns, self._convention, sigma, w),
            )
            self._set_text(
                "poe",
                self._poe_text,
                panel.poe_text(subject, snap, self._k, self._form, self._unit),
            )
            self._set_text(
                "screws", self._screws_text, panel.screws_text(subject, snap, self._form)
            )
            self._texts["q"] = " ".join(f"{v + 0.0:.6g}" for v in snap.qpos)
            if self.comparison is not None:
                self._refresh_ghost(snap)
            self._refresh_ik(snap)
            if self._handles is not None:
                self._refresh_wholebody(snap)
            self._refresh_collision()
            self._send_poses()
        self.server.flush()

    def _refresh_screws(self, snap: Snapshot) -> None:
        show = self._show_screws.value
        ref = snap.T[:3, 3] if self._form == "body" else np.zeros(3)
        levers = np.zeros((max(self.subject.n_joints, 1), 2, 3))
        poses = axis_pose(snap.points, _directions(snap.screws))
        for i, S in enumerate(snap.screws):
            name = f"/screws/s{i}"
            self._pose(name, poses[i])
            self._nodes[name].handle.visible = show
            levers[i] = [ref, nearest_point(S, snap.points[i], ref)]
        lever = self._nodes["/levers"].handle
        lever.visible = show and self._show_levers.value
        if lever.visible:
            lever.points = levers.astype(np.float32)

    def _refresh_poe(self, snap: Snapshot) -> None:
        n, k = self.subject.n_joints, self._k
        stepping = k < n
        for j in range(n + 1):
            name = f"/poe/t{j}"
            if stepping and j <= k:
                self._pose(name, snap.partial[j])
            self._nodes[name].handle.visible = stepping and j <= k
        label = self._nodes["/poe/label"].handle
        label.visible = stepping
        label.position = snap.partial[k][:3, 3]
        label.text = f"T{k}"
        path = self._nodes["/poe/path"].handle
        path.visible = stepping and k > 0
        if path.visible:
            origins = snap.partial[: k + 1, :3, 3]
            segs = np.zeros((max(n, 1), 2, 3))
            segs[:k] = np.stack([origins[:-1], origins[1:]], axis=1)
            segs[k:] = origins[-1]
            path.points = segs.astype(np.float32)

    def _refresh_dh(self) -> None:
        show = self._show_dh.value
        table = self.subject.dh(self._dh_convention)
        self._set_text("dh", self._dh_text, panel.dh_text(table))
        frames = dh_frames(self.subject, table, self._qpos) if show else None
        for i in range(self.subject.n_joints + 2):
            name = f"/dh/f{i}"
            self._nodes[name].handle.visible = show
            self._nodes[f"{name}/label"].handle.visible = show
            if frames is not None:
                self._pose(name, frames[i])

    def _refresh_ghost(self, snap: Snapshot) -> None:
        assert self.comparison is not None
        gh = ghost(self.comparison, snap, aligned=self._aligned)
        stops = np.vstack([gh.links[0][None, :3, 3], gh.points, gh.T[None, :3, 3]])
        arm = self._nodes["/ghost/arm"].handle
        arm.points = np.stack([stops[:-1], stops[1:]], axis=1).astype(np.float32)
        poses = axis_pose(gh.points, _directions(gh.screws))
        for i in range(len(gh.screws)):
            self._pose(f"/ghost/s{i}", poses[i])
            self._nodes[f"/ghost/s{i}"].handle.visible = self._show_screws.value
        self._pose("/ghost/end", gh.T)
        self._pose("/ghost/home", gh.home)
        self._set_text(
            "compare", self._compare_text, panel.compare_text(self.comparison, gh, self._aligned)
        )

    def _refresh_ik(self, snap: Snapshot) -> None:
        """The IK mode's nodes and texts; all hidden when it is off. A configuration set by
        other means (a slider, a button, ``q``) puts the target at the end frame."""
        on = bool(self._ik_input.value)
        for name in ("/ik/target", "/ik/target/marker", "/ik/target/label"):
            _set(self._nodes[name].handle, "visible", on)
        if not on:
            _set(self._nodes["/ik/miss"].handle, "visible", False)
            self._show_solutions(snap, None)
            self._texts.pop("ik", None)
            return
        shown = self._reach
        if shown is None or not np.array_equal(shown.qpos, snap.qpos):
            shown = self._reach = follow(
                self.subject,
                snap.qpos,
                position_only=bool(self._ik_position_input.value),
                ik_support=self._ik_support,
            )
            self._ik_solve_s = None
            self._pose("/ik/target", shown.target)
        color = TARGET_COLOR if shown.success else UNREACHABLE_COLOR
        _set(self._nodes["/ik/target/marker"].handle, "color", color)
        _set(
            self._nodes["/ik/target/label"].handle,
            "text",
            "IK target"
            if shown.success
            else f"unreachable: {panel.residual_words(shown.pos_err, shown.ori_err)}",
        )
        miss = self._nodes["/ik/miss"].handle
        _set(miss, "visible", not shown.success)
        if miss.visible:
            miss.points = np.array([[snap.T[:3, 3], shown.target[:3, 3]]], dtype=np.float32)
        self._show_solutions(snap, shown)
        self._set_text(
            "ik",
            self._ik_text,
            panel.ik_text(
                shown,
                self._ik_support,
                position_only=bool(self._ik_position_input.value),
                solve_s=self._ik_solve_s,
            ),
        )
        _set(self._target_input, "value", _pose_words(shown.target))

    def _refresh_wholebody(self, snap: Snapshot) -> None:
        """The whole-body handles' markers, labels, miss lines and text. A configuration set
        by other means (a slider, a button, ``q``, the one-frame IK mode) puts every target at
        its frame."""
        tree, handles = self.subject.tree, self._handles
        assert tree is not None and handles is not None
        shown = self._wb
        if shown is None or not np.array_equal(shown.qpos, snap.qpos):
            shown = self._wb = wholebody.follow(tree, handles, snap.qpos)
            self._wb_solve_s = None
            self._wb_note = ""
            self._pose_handles(shown)
        segments = np.zeros((len(handles.frames), 2, 3))
        for i, frame in enumerate(handles.frames):
            missed, held = shown.missed(frame), frame in handles.hold
            color = UNREACHABLE_COLOR if missed else HELD_COLOR if held else TARGET_COLOR
            _set(self._nodes[f"/wholebody/h{i}/marker"].handle, "color", color)
            text = f"{frame} (held)" if held else frame
            if missed:
                text += f": {panel.residual_words(*shown.frame_errors[frame])}"
                at = snap.frames[tree.frame_index(frame), :3, 3]
                segments[i] = [at, shown.targets[frame][:3, 3]]
            _set(self._nodes[f"/wholebody/h{i}/label"].handle, "text", text)
        miss = self._nodes["/wholebody/miss"].handle
        _set(miss, "visible", not shown.success)
        if miss.visible:
            miss.points = segments.astype(np.float32)
        self._set_text(
            "wholebody",
            self._wb_text,
            panel.wholebody_text(shown, solve_s=self._wb_solve_s, note=self._wb_note),
        )

    def _show_solutions(self, snap: Snapshot, shown: Reach | None) -> None:
        """The ghosts of the other closed-form solutions (none for ``shown`` None), their
        numbers, and the picker's choices."""
        ghosts = [] if shown is None or not self._show_solutions_input.value else shown.ghosts
        if ghosts and not self._solution_meshes and self._geometry is not None:
            self._build_solution_meshes(self._geometry)
        if ghosts:
            assert shown is not None
            bodies, anchors = ghost_poses(self.subject, shown.solutions[ghosts])
            quats = _quat(bodies[..., :3, :3])  # (ghosts, bodies, 4): one batched conversion
        for name in self.node_names("solution"):
            node = self._nodes[name]
            _set(node.handle, "visible", bool(ghosts))
            if ghosts:
                node.handle.batched_wxyzs = quats[:, node.index]
                node.handle.batched_positions = bodies[:, node.index, :3, 3]
        # a number by each ghost (and the arm's, if it is one of the solutions), at the joint
        # whose place differs most between them (a UR's elbow); numbers that would overlap
        # share one label
        groups: list[tuple[FloatArray, list[str]]] = []
        if ghosts:
            assert shown is not None
            arm = joint_anchors(self.subject, snap.bodies)
            every = np.concatenate([arm[None], anchors])
            spread = int(np.argmax(np.sum(np.var(every, axis=0), axis=-1)))
            places = [(anchors[i, spread], str(k + 1)) for i, k in enumerate(ghosts)]
            if shown.current >= 0:
                places.insert(0, (arm[spread], f"{shown.current + 1} (the arm)"))
            for at, number in places:
                near = [g for g in groups if np.linalg.norm(g[0] - at) < 0.08 * self._extent]
                if near:
                    near[0][1].append(number)
                else:
                    groups.append((at, [number]))
        for j, (at, numbers) in enumerate(groups):
            label = self._solution_label(j)
            _set(label, "text", ", ".join(numbers))
            label.position = at
            _set(label, "visible", True)
        for name in self.node_names("solution_label"):
            if self._nodes[name].index >= len(groups):
                _set(self._nodes[name].handle, "visible", False)
        choices = [_NO_SOLUTION]
        if shown is not None:
            kinds = self.subject.chain.joint_types
            for k, x in enumerate(shown.solutions):
                q = self.subject.chain_q(x)
                choices.append(panel.solution_label(k, q, kinds, self._unit))
        self._syncing = True
        try:
            if tuple(self._solution_input.options) != tuple(choices):
                self._solution_input.options = choices
            current = -1 if shown is None else shown.current
            _set(self._solution_input, "value", choices[current + 1])
        finally:
            self._syncing = False


def _set(handle: Any, name: str, value: Any) -> None:
    """Set a node's or control's property only if it changes (each set is a message)."""
    if not np.array_equal(getattr(handle, name), value):
        setattr(handle, name, value)


def _pose_words(T: FloatArray) -> str:
    """``x y z qw qx qy qz`` of a pose, as the target box shows and reads it."""
    numbers = [*T[:3, 3], *_quat(T[:3, :3])]
    return " ".join(f"{v + 0.0:.6g}" for v in numbers)


def _pose_from_text(text: str) -> FloatArray:
    """A pose from ``x y z qw qx qy qz`` (commas and brackets allowed); the quaternion must
    have a norm within 1e-3 of 1 (typed decimals) and is normalised.

    Raises:
        InputError: not seven numbers, or not a unit quaternion.
    """
    words = text.replace(",", " ").replace("[", " ").replace("]", " ").split()
    try:
        values = [float(w) for w in words]
    except ValueError:
        raise InputError(f"the target is 7 numbers, x y z qw qx qy qz; got {text!r:.60}") from None
    if len(values) != 7 or not all(math.isfinite(v) for v in values):
        raise InputError(
            f"the target is 7 finite numbers, x y z qw qx qy qz; got {len(values)}: {text!r:.60}"
        )
    quat = np.array(values[3:])
    norm = float(np.linalg.norm(quat))
    if abs(norm - 1.0) > 1e-3:
        raise InputError(f"qw qx qy qz must be a unit quaternion; its norm is {norm:.6g}")
    T = np.eye(4)
    T[:3, :3] = lie.quat_to_rotation(quat / norm)
    T[:3, 3] = values[:3]
    return T


def _directions(screws: FloatArray) -> FloatArray:
    """``(n, 3)`` each screw's direction: ``w``, or ``v`` for a prismatic one."""
    turning = np.any(screws[:, :3] != 0.0, axis=1, keepdims=True)
    return np.where(turning, screws[:, :3], screws[:, 3:])


def _turn_marker(kind: str, pitch: float, extent: float) -> FloatArray:
    """``(N, 2, 3)`` segments around the z axis: a 3/4 circle with an arrowhead for the
    positive turn (right-hand rule), a helix climbing ``pitch`` per radian for a pitched
    screw, ticks across the axis for a prismatic one."""
    r = 0.045 * extent
    if kind == "prismatic":
        z = np.linspace(0.03, 0.17, 5) * extent
        a = np.stack(
            [
                np.stack([-r / 2 * np.ones_like(z), np.zeros_like(z), z], -1),
                np.stack([r / 2 * np.ones_like(z), np.zeros_like(z), z], -1),
            ],
            1,
        )
        return a.astype(np.float64)
    turns = 2.0 if kind == "pitched" else 0.75
    t = np.linspace(0.0, 2 * math.pi * turns, int(48 * turns) + 1)
    climb = np.clip(pitch, -0.1 * extent, 0.1 * extent) if kind == "pitched" else 0.0
    pts = np.stack([r * np.cos(t), r * np.sin(t), 0.06 * extent + climb * t], -1)
    segs = np.stack([pts[:-1], pts[1:]], axis=1)
    tip, tangent = pts[-1], pts[-1] - pts[-2]
    tangent /= np.linalg.norm(tangent)
    radial = np.array([math.cos(t[-1]), math.sin(t[-1]), 0.0])
    head = 0.35 * r
    wings = np.array(
        [
            [tip, tip - head * tangent + 0.6 * head * radial],
            [tip, tip - head * tangent - 0.6 * head * radial],
        ]
    )
    return np.concatenate([segs, wings]).astype(np.float64)


def _start_server(host: str, port: int | None) -> viser.ViserServer:
    """A viser server on ``host:port``; port None: 8080 or the next free one.

    Raises:
        InputError: ``port`` was given and is in use (viser itself would take the next one).
    """
    requested = DEFAULT_PORT if port is None else port
    if not 0 <= requested <= 65535:
        raise InputError(f"--port must be in 0..65535, got {requested}")
    with contextlib.redirect_stdout(io.StringIO()):
        try:
            server = viser.ViserServer(host=host, port=requested, verbose=False)
        except OSError as exc:
            raise InputError(f"cannot serve on {host}:{requested}: {exc.strerror or exc}") from None
    if port not in (None, 0) and server.get_port() != port:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
        raise InputError(
            f"port {port} on {host} is in use; choose another with --port, or --port 0 for any "
            "free port"
        )
    return server


def _geometry_loader(shown: Shown) -> Callable[[Subject], Geometry]:
    if shown.loaded is not None:
        loaded = shown.loaded
        return lambda s: mjcf_geometry(loaded, s)
    if shown.urdf is not None:
        urdf = shown.urdf
        return lambda s: urdf_geometry(urdf, s)
    why = "" if shown.subject.tree is None else "a Tree has no meshes: pass its model file"
    return lambda s: stand_in(s, why)


def _collision_scene_of(subject: Subject, obstacles: tuple[Obstacle, ...]) -> CollisionScene:
    """The subject's collision geoms and the obstacles.

    Raises:
        InputError: a bare parameter set (it has no collision geometry), or bad obstacles.
        ModelError: a tree that knows no model file, or whose collision meshes are missing.
    """
    if subject.tree is None:
        raise InputError(
            "collision needs a model's collision geometry: show a model (a Menagerie name, an "
            "MJCF or URDF file), not a bare parameter set"
        )
    return collision_scene(subject.tree, obstacles)


def _in_jupyter() -> bool:
    try:
        from IPython import get_ipython  # type: ignore[attr-defined]
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and "IPKernelApp" in getattr(shell, "config", {})


def view(
    model: str | os.PathLike[str] | Tree | Chain | DHTable | Any = "universal_robots_ur5e",
    *,
    frame: str | None = None,
    params: str | os.PathLike[str] | Chain | DHTable | None = None,
    port: int | None = None,
    host: str = "127.0.0.1",
    open_browser: bool | None = None,
    base: ArrayLike | None = None,
    tool: ArrayLike | None = None,
    ik: bool = False,
    frames: str | Sequence[str] | None = None,
    hold: str | Sequence[str] | None = None,
    play: str | os.PathLike[str] | Trajectory | None = None,
    play_name: str | None = None,
    collision: bool = False,
    obstacles: Obstacle | Sequence[Obstacle] = (),
) -> Viewer:
    """Show a robot in the browser: sliders for its joints, its screw axes, ``T(q)``, its
    Jacobian, the PoE step by step, DH frames, and a parameter set beside it.

    Args:
        model: a Menagerie robot name, an MJCF or URDF path, a loaded model, a :class:`Tree`,
            or a bare :class:`Chain` / :class:`DHTable` (drawn as capsules).
        frame: the end frame (a body or site); default: the model's only site, else the frame
            with the most joints on its path (a dropdown on the page changes it).
        params: your parameters (a file or named set, as ``poekin diagnose --params`` takes, or
            a chain or table): drawn as an orange ghost driven by the same joint values, with
            ``diagnose``'s findings and the live end-frame error.
        port: the port; None: 8080, or the next free one. One that is in use is an error.
        host: the interface to serve on; the default is reachable from this machine only.
        open_browser: open the page in the web browser; None: yes, except in a Jupyter kernel,
            where the handle shows the page inline.
        base: ``T_world_base``, where the robot stands in your world (a ``(4, 4)`` rigid
            transform or ``x y z qw qx qy qz``): the whole model is drawn there
            (:meth:`Tree.with_base`).
        tool: ``T_frame_tool``, a tool on the end frame, given as ``base`` is: the end frame
            drawn (and dragged in the IK mode) is the tool's, the tool a capsule from the frame
            that carries it (:meth:`Chain.with_tool`).
        ik: start in the IK mode: the target handle on the end frame (the panel's "IK
            target" box ticked).
        frames: whole-body IK (:mod:`poekin.viewer.wholebody`): a handle on each of these
            frames of a tree (names, or one comma-separated string); a drag of one solves the
            whole robot with :meth:`Tree.ik` (the others keep their targets).
        hold: some of ``frames`` met exactly whatever the drag (contacts: the feet).
        play: a trajectory to play (:mod:`poekin.viewer.play`): a ``.npz`` file
            (:func:`~poekin.io.trajectory.load_trajectory`) or a
            :class:`~poekin.io.trajectory.Trajectory` of the robot's ``qpos`` or of its chain's
            joint values: a time slider (s), a play/pause button that plays it in real time,
            and the end frame's path as a tool trace.
        play_name: how messages name the trajectory (the command line's ``--play FILE``);
            default ``play FILE``.
        collision: show the model's collision geoms from the start (the panel's "collision
            geometry" box ticked; :mod:`poekin.viewer.collision`): see-through, following the
            robot, the two shapes of a penetrating pair red, and the witness points of every
            pair closer than the margin (20 mm; the "collision margin [mm]" slider), queried
            once per new configuration with :meth:`Tree.distances`.
        obstacles: world obstacles (:class:`poekin.collision.Box`, ``Sphere``, ``Capsule``,
            ``Plane``, ``Mesh``; in the world or on a frame), always drawn, and checked against
            the robot while the collision geometry is shown.

    Returns:
        The :class:`Viewer`; ``viewer.q = ...`` poses the robot, ``viewer.close()`` stops it.

    Raises:
        PoekinError: an unknown robot, frame or parameter set, a port in use, ``hold``
            without ``frames`` or naming a frame not among them, ``ik`` on an end frame the IK
            mode does not apply to, a trajectory file that is bad or made for another robot,
            and the like; ``collision`` or ``obstacles`` for a bare parameter set, a model
            whose collision meshes are missing, bad obstacles.
    """
    if hold is not None and frames is None:
        raise InputError("hold names some of the whole-body frames: give frames too")
    trajectory = None if play is None else trajectory_from(play, "play")
    shown = load_shown(model, frame, base=base, tool=tool)
    subject = shown.subject
    handles = None
    if frames is not None:
        if subject.tree is None:
            raise InputError("whole-body IK needs a tree: a model, not a bare parameter set")
        handles = wholebody.check_handles(subject.tree, frames, hold)
    played = None
    if play is not None and trajectory is not None:
        named = play_name or (
            "the trajectory" if isinstance(play, Trajectory) else f"play {os.fspath(play)}"
        )
        played = playback_of(subject, trajectory, named)
    comparison = load_params_comparison(subject, params)
    viewer = Viewer(
        subject,
        geometry=_geometry_loader(shown),
        comparison=comparison,
        handles=handles,
        playback=played,
        collision=collision,
        obstacles=obstacles,
        host=host,
        port=port,
    )
    if ik and handles is None:
        try:
            viewer.set_option("IK target", True)
        except BaseException:
            viewer.close()
            raise
    if open_browser is None:
        open_browser = not _in_jupyter()
    if open_browser:
        threading.Thread(target=webbrowser.open, args=(viewer.url,), daemon=True).start()
    return viewer
