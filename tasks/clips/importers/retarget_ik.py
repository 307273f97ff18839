"""The inverse kinematics under retargeting: the walker's free joint and 56 hinges fitted to body targets.

Solved with mink (differential inverse kinematics on MuJoCo's Jacobians, each step a small quadratic
program whose inequalities keep every hinge within its limits), an optional dependency:
``pip install 'mocap-hierarchy[retarget]'``. mink 1.3.0 installs beside the pinned ``mujoco==3.17.0`` and
``numpy`` without changing either (checked with ``pip install --dry-run``), so the library uses it rather
than its own damped least squares (:mod:`tasks.clips.synthetic.ik`), which clips at the limits instead
of solving with them.

Each body target is a mink ``FrameTask`` (position and orientation costs from the joint map); a small
posture task pulls the hinges towards the previous frame's solution, which both smooths the motion and
settles what the targets leave free (a hinge no mapped body depends on). A frame is iterated
(Gauss-Newton steps of the quadratic program) until the largest step is below
:data:`STEP_TOLERANCE` radians or metres, 10 steps at most (a warm-started frame at 15-120 Hz needs
fewer; more changed nothing measurable on the tests' motions). Solutions are clipped to the limits at
the end, where the quadratic program's tolerance may leave them a hair outside.
"""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Iterator
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from tasks.clips.importers.trajectory import MotionImportError
from tasks.walker import WalkerModel

if TYPE_CHECKING:
    import mink

INSTALL_HINT = "pip install 'mocap-hierarchy[retarget]'"

QP_SOLVER = "daqp"
"""mink's quadratic-program back end (installed with mink through ``qpsolvers[daqp]``)."""

STEP_TOLERANCE = 1e-4
"""A frame's iterations stop when no coordinate moves more than this (radians or metres)."""

POSTURE_COST = 1e-3
"""Weight (per radian) of the pull towards the previous frame's hinge angles."""

COARSE_STEPS = 5
"""Grid points per hinge of :meth:`RetargetSolver.coarse_start`."""

DAMPING = 1e-6
"""Levenberg-Marquardt damping of every step (keeps a step bounded where the targets leave dofs free)."""


def import_mink():
    """The ``mink`` module, or an ``ImportError`` saying which extra installs it."""
    try:
        import mink
    except ImportError as error:
        raise ImportError(
            f"retargeting a BVH file needs the mink inverse-kinematics library ({error}); "
            f"install it with: {INSTALL_HINT}"
        ) from None
    return mink


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Holds NumPy's BLAS to one thread (with threadpoolctl, installed by the ``retarget`` extra).

    Each step multiplies matrices of a few hundred rows, far too small to share among threads: with
    OpenBLAS's threads on two busy cores the solver ran over 20 times slower (23 against 554 frames per
    second on the 165-frame run of the tests). Without threadpoolctl nothing changes.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


class RetargetSolver:
    """Fits the walker's whole ``qpos`` to position and orientation targets of some of its bodies.

    Args:
        walker: The walker.
        bodies: Walker body ids with targets, in the order targets are given.
        position_weights: ``(bodies,)`` weights of the position errors (per metre).
        orientation_weights: ``(bodies,)`` weights of the orientation errors (per radian).
        max_iterations: Steps per frame at most (a warm-started frame needs a few).
        posture_cost: See :data:`POSTURE_COST`.
    """

    def __init__(
        self,
        walker: WalkerModel,
        bodies: np.ndarray,
        position_weights: np.ndarray,
        orientation_weights: np.ndarray,
        max_iterations: int = 10,
        posture_cost: float = POSTURE_COST,
    ) -> None:
        mink = import_mink()
        self._mink = mink
        self.walker = walker
        model = walker.model
        self.configuration = mink.Configuration(model)
        self.bodies = np.asarray(bodies, dtype=int)
        self.orientation_weights = np.asarray(orientation_weights, dtype=float)
        self.tasks: list[mink.FrameTask] = [
            mink.FrameTask(int(body), "body", position_cost=float(p), orientation_cost=float(o))
            for body, p, o in zip(self.bodies, position_weights, orientation_weights, strict=True)
        ]
        self.posture = mink.PostureTask(model, cost=posture_cost)
        self.limits = [mink.ConfigurationLimit(model, gain=1.0)]
        self.max_iterations = max_iterations
        self._hinges = walker.mocap_qpos
        joints = [int(np.flatnonzero(model.jnt_qposadr == address)[0]) for address in self._hinges]
        self._range = model.jnt_range[joints].copy()

    def set_weights(self, position_weights: np.ndarray, orientation_weights: np.ndarray) -> None:
        """Changes the weights of the body targets (same order as ``bodies``)."""
        self.orientation_weights = np.asarray(orientation_weights, dtype=float)
        for task, p, o in zip(self.tasks, position_weights, self.orientation_weights, strict=True):
            task.set_position_cost(float(p))
            task.set_orientation_cost(float(o))

    def coarse_start(self, positions: np.ndarray, rotations: np.ndarray, steps: int = COARSE_STEPS) -> None:
        """Sets each body's hinges, root to leaves, to the best of a grid over their ranges (a first frame's start).

        From one start pose, steps that keep to the joint limits can end against a limit in the wrong
        fold (an arm swung backwards instead of down); a coarse search over each joint's range, scored
        on the targets of the body and everything below it, starts every limb in the right fold.

        Args:
            positions: ``(bodies, 3)`` target positions.
            rotations: ``(bodies, 3, 3)`` target rotations.
            steps: Grid points per hinge.
        """
        model = self.walker.model
        data = self.configuration.data
        qpos = self.configuration.q.copy()
        position_weights = np.array([task.cost[0] for task in self.tasks])
        for body in range(model.nbody):
            joints = [
                j
                for j in range(model.njnt)
                if model.jnt_bodyid[j] == body and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
            ]
            scored = [i for i, target in enumerate(self.bodies) if _descends(model, int(target), body)]
            if not joints or not scored:
                continue
            addresses = model.jnt_qposadr[joints]
            grids = [np.linspace(model.jnt_range[j, 0], model.jnt_range[j, 1], steps) for j in joints]
            candidates = [qpos[addresses].copy(), *itertools.product(*grids)]
            costs = []
            for candidate in candidates:
                data.qpos[:] = qpos
                data.qpos[addresses] = candidate
                mujoco.mj_kinematics(model, data)
                costs.append(self._cost(data, scored, positions, rotations, position_weights))
            qpos[addresses] = candidates[int(np.argmin(costs))]
        self.configuration.update(qpos)

    def _cost(
        self, data: mujoco.MjData, scored: list[int], positions: np.ndarray, rotations: np.ndarray, weights: np.ndarray
    ) -> float:
        bodies = self.bodies[scored]
        position = np.sum((weights[scored, None] * (data.xpos[bodies] - positions[scored])) ** 2)
        current = data.xmat[bodies].reshape(-1, 3, 3)
        cosine = (np.einsum("bij,bij->b", current, rotations[scored]) - 1.0) / 2.0
        angle = np.arccos(np.clip(cosine, -1.0, 1.0))
        return float(position + np.sum((self.orientation_weights[scored] * angle) ** 2))

    @property
    def qpos(self) -> np.ndarray:
        """The current solution (a copy)."""
        return self.configuration.q.copy()

    def reset(self, qpos: np.ndarray) -> None:
        """Starts from ``qpos`` (the next :meth:`solve` warm-starts from it)."""
        self.configuration.update(np.asarray(qpos, dtype=float).copy())

    def solve(self, positions: np.ndarray, rotations: np.ndarray, max_iterations: int | None = None) -> np.ndarray:
        """Fits one frame, warm-started from the last solution, hinges within their limits.

        Args:
            positions: ``(bodies, 3)`` target positions (world, metres).
            rotations: ``(bodies, 3, 3)`` target rotations (world); ignored where the orientation
                weight is zero.
            max_iterations: Overrides the solver's cap for this frame (the first frame needs more).

        Returns:
            The frame's ``qpos``.
        """
        mink = self._mink
        configuration = self.configuration
        data = configuration.data
        self.posture.set_target(configuration.q)
        for task, body, weight, position, rotation in zip(
            self.tasks, self.bodies, self.orientation_weights, positions, rotations, strict=True
        ):
            # A body whose orientation is free aims at its current one: its position error is then the
            # plain difference of positions, not one bent by an orientation error it does not weigh.
            target = rotation if weight > 0 else data.xmat[body].reshape(3, 3)
            task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(target), position))
        tasks = [*self.tasks, self.posture]
        for _ in range(max_iterations or self.max_iterations):
            try:
                velocity = mink.solve_ik(configuration, tasks, 1.0, QP_SOLVER, damping=DAMPING, limits=self.limits)
            except mink.NoSolutionFound as error:
                raise MotionImportError(
                    f"the inverse kinematics found no step within the joint limits ({error})"
                ) from None
            configuration.integrate_inplace(velocity, 1.0)
            if np.max(np.abs(velocity)) < STEP_TOLERANCE:
                break
        qpos = configuration.q.copy()
        # The quadratic program holds the limits up to its solver's tolerance; make them exact.
        qpos[self._hinges] = np.clip(qpos[self._hinges], self._range[:, 0], self._range[:, 1])
        qpos[3:7] /= np.linalg.norm(qpos[3:7])
        configuration.update(qpos)
        return qpos


def body_poses(walker: WalkerModel, qpos: np.ndarray, bodies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions ``(frames, bodies, 3)`` and rotations ``(frames, bodies, 3, 3)`` of ``bodies`` over ``qpos``."""
    model, data = walker.model, walker.new_data()
    qpos = np.atleast_2d(qpos)
    positions = np.zeros((len(qpos), len(bodies), 3))
    rotations = np.zeros((len(qpos), len(bodies), 3, 3))
    for frame, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        positions[frame] = data.xpos[bodies]
        rotations[frame] = data.xmat[bodies].reshape(-1, 3, 3)
    return positions, rotations


def _descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    """Whether ``body`` is ``ancestor`` or below it in the model's tree."""
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return False
