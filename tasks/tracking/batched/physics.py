"""Many copies of the walker's physics on MuJoCo Warp, stepped together, read as torch tensors.

:class:`WarpPhysics` owns the Warp model and data of ``N`` worlds and advances
them exactly as :func:`tasks.simulation.control_step` advances one: six
physics steps of 0.005 s with the new controls, then a forward pass so the
acceleration-stage sensors (touch, torque, accelerometer) describe the final
state. A reset writes reference poses into chosen worlds and runs the forward
pass without actuation (dm_control's state after a reset) while the other
worlds keep what their last step computed.

Every array the environments read is a zero-copy torch view of Warp's memory
(:attr:`WarpPhysics.view`), so nothing goes through the host per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import torch

from tasks.simulation import PHYSICS_STEPS_PER_CONTROL_STEP
from tasks.tracking.batched.backend import require_warp


@dataclass(frozen=True)
class ContactCapacity:
    """Per-world room for contacts and constraint rows (MuJoCo Warp preallocates both).

    Attributes:
        contacts: Contacts per world (the humanoid on a floor has well under 40).
        constraints: Constraint rows per world (4 per pyramidal contact, plus joint limits).
    """

    contacts: int = 64
    constraints: int = 320


class PhysicsCapacityError(RuntimeError):
    """A world produced more contacts or constraint rows than were allocated."""


class WarpPhysics:
    """``num_worlds`` copies of one MuJoCo model on a Warp device.

    Args:
        model: The compiled MuJoCo model (every world simulates it).
        num_worlds: Number of worlds.
        warp_device: Warp device name (``cpu`` or ``cuda:N``).
        capacity: Contacts and constraint rows to allocate per world.
        subtree_velocity: Also compute ``subtree_linvel`` after each step (some observables need it).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        num_worlds: int,
        warp_device: str,
        capacity: ContactCapacity | None = None,
        subtree_velocity: bool = False,
    ) -> None:
        if num_worlds < 1:
            raise ValueError(f"num_worlds must be positive, got {num_worlds}")
        self.wp, self.mjw = require_warp()
        self.num_worlds = num_worlds
        self.capacity = capacity or ContactCapacity()
        self.subtree_velocity = subtree_velocity
        self.device = warp_device
        self._actuation_off = int(model.opt.disableflags | mujoco.mjtDisableBit.mjDSBL_ACTUATION)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with self.wp.ScopedDevice(warp_device):
            self.model = self.mjw.put_model(model)
            self.data = self.mjw.put_data(
                model,
                data,
                nworld=num_worlds,
                nconmax=self.capacity.contacts,
                njmax=self.capacity.constraints,
            )
        self.wp.synchronize_device(warp_device)  # the uploads ran on Warp's stream; torch reads next
        self.model.opt.warn_overflow = 0  # overflows are checked and reported by check_capacity
        self._flags = int(self.model.opt.disableflags)
        self.view = TorchViews(self.wp, self.data)
        self._graph = None
        self.capture_graph = True  # on CUDA, replay each control step as one captured graph (False: launch by launch)
        # Warp runs on torch's current CUDA stream, so torch's writes (controls, resets) and
        # Warp's kernels (and its captured graph) are ordered without extra synchronisation.
        self._stream = None
        if warp_device != "cpu":
            self._stream = self.wp.stream_from_torch(torch.cuda.current_stream(warp_device))

    def _on_device(self):
        """Warp's scope for this engine: its device, and on CUDA torch's stream."""
        if self._stream is None:
            return self.wp.ScopedDevice(self.device)
        return self.wp.ScopedStream(self._stream)

    # Stepping ------------------------------------------------------------------

    def control_step(self, ctrl: torch.Tensor) -> None:
        """Sets the controls ``(N, nu)`` and advances every world one control step (0.03 s)."""
        self.view.ctrl.copy_(ctrl)
        if self.device == "cpu" or not self.capture_graph:
            self._advance()
        elif self._graph is None:
            self._advance()  # compiles every kernel before capture
            with self._on_device(), self.wp.ScopedCapture() as capture:
                self._advance()
            self._graph = capture.graph
        else:
            with self._on_device():
                self.wp.capture_launch(self._graph)
        if self.subtree_velocity:  # allocates its scratch arrays, so it stays out of the captured graph
            with self._on_device():
                self.mjw.subtree_vel(self.model, self.data)

    def _advance(self) -> None:
        with self._on_device():
            for _ in range(PHYSICS_STEPS_PER_CONTROL_STEP):
                self.mjw.step(self.model, self.data)
            self.mjw.forward(self.model, self.data)

    def reset_worlds(self, worlds: torch.Tensor, qpos: torch.Tensor, qvel: torch.Tensor) -> None:
        """Resets the worlds in the bool mask ``worlds`` to the given poses, others untouched.

        As ``mj_resetData``, then ``qpos``/``qvel`` (rows for the reset worlds
        only), then a forward pass without actuation. The forward pass runs for
        every world; only the acceleration-stage sensors depend on actuation, so
        the other worlds keep theirs.
        """
        view = self.view
        with self._on_device():
            self.mjw.reset_data(self.model, self.data, reset=self.wp.from_torch(worlds.contiguous()))
        view.qpos[worlds] = qpos.to(view.qpos.dtype)
        view.qvel[worlds] = qvel.to(view.qvel.dtype)
        kept_sensors = view.sensordata.clone()
        kept_subtree = view.subtree_linvel.clone()
        self._forward(actuation=False)
        view.sensordata.copy_(torch.where(worlds[:, None], view.sensordata, kept_sensors))
        # dm_control refreshes subtree velocities only after physics steps: a reset reports zeros.
        view.subtree_linvel.copy_(torch.where(worlds[:, None, None], torch.zeros_like(kept_subtree), kept_subtree))

    def load_state(
        self,
        worlds: torch.Tensor,
        qpos: torch.Tensor,
        qvel: torch.Tensor,
        act: torch.Tensor,
        qacc_warmstart: torch.Tensor,
        subtree_linvel: torch.Tensor | None = None,
    ) -> None:
        """Writes a full physics state into the worlds at indices ``worlds`` and recomputes what follows from it.

        For checks against the CPU env: the result equals a ``mj_forward`` of
        the same state (with actuation), which is what a CPU control step leaves.
        """
        view = self.view
        for target, value in ((view.qpos, qpos), (view.qvel, qvel), (view.act, act)):
            target[worlds] = value.to(target.dtype)
        view.qacc_warmstart[worlds] = qacc_warmstart.to(view.qacc_warmstart.dtype)
        kept = view.sensordata.clone()
        self._forward(actuation=True)
        mask = torch.zeros(self.num_worlds, dtype=torch.bool, device=kept.device)
        mask[worlds] = True
        view.sensordata.copy_(torch.where(mask[:, None], view.sensordata, kept))
        if subtree_linvel is not None:
            view.subtree_linvel[worlds] = subtree_linvel.to(view.subtree_linvel.dtype)

    def _forward(self, actuation: bool) -> None:
        self.model.opt.disableflags = self._flags if actuation else self._flags | self._actuation_off
        try:
            with self._on_device():
                self.mjw.forward(self.model, self.data)
        finally:
            self.model.opt.disableflags = self._flags

    # Health ----------------------------------------------------------------------

    def unstable_worlds(self) -> torch.Tensor:
        """Bool mask ``(N,)`` of worlds whose state is no longer finite (the simulation blew up)."""
        view = self.view
        return ~(torch.isfinite(view.qpos).all(1) & torch.isfinite(view.qvel).all(1) & torch.isfinite(view.act).all(1))

    def check_capacity(self) -> None:
        """Raises :class:`PhysicsCapacityError` if any world ran out of contact or constraint room.

        Costs one device-to-host copy of a small flag; call it every few steps.
        """
        overflow = self.view.overflow
        if bool((overflow != 0).any()):
            worlds = torch.nonzero(overflow).flatten()[:8].tolist()
            raise PhysicsCapacityError(
                f"worlds {worlds} ran out of room for contacts or constraints ({self.capacity}); raise "
                "ContactCapacity(contacts=..., constraints=...) for this batch: dropped contacts would change "
                "the physics silently"
            )


class TorchViews:
    """Zero-copy torch tensors over the Warp data arrays the environments read and write."""

    def __init__(self, wp, data) -> None:
        def view(array) -> torch.Tensor:
            return wp.to_torch(array, requires_grad=False)

        self.qpos = view(data.qpos)
        self.qvel = view(data.qvel)
        self.act = view(data.act)
        self.ctrl = view(data.ctrl)
        self.qacc_warmstart = view(data.qacc_warmstart)
        self.xpos = view(data.xpos)
        self.xquat = view(data.xquat)
        self.xmat = view(data.xmat)
        self.subtree_com = view(data.subtree_com)
        self.subtree_linvel = view(data.subtree_linvel)
        self.sensordata = view(data.sensordata)
        self.overflow = view(data.overflow)
