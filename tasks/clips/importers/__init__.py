"""Motion import: a user's recordings (CMU ASF/AMC, BVH) turned into clips of the V2020 walker.

One reader per input format turns a recording into a :class:`~tasks.clips.importers.trajectory.JointTrajectory`
(the walker's root and 56 hinge angles at the recording's frame rate); one shared pipeline then
resamples it to the control step, puts the feet on the floor and computes every clip feature:

* :mod:`~tasks.clips.importers.asf` and :mod:`~tasks.clips.importers.amc`: CMU's own skeleton and motion files
  (the AMC values map one to one onto the walker's hinges, as dm_control's converter maps them);
* :mod:`~tasks.clips.importers.bvh`: BVH files; :mod:`~tasks.clips.importers.cmu_bvh` converts the common
  CMU conversion exactly, :mod:`~tasks.clips.importers.retarget` any other skeleton by inverse kinematics
  through a joint map (:mod:`~tasks.clips.importers.joint_map`);
* :mod:`~tasks.clips.importers.resample` (frame rate to the 0.03 s control step, the CMU 2020 length rule),
  :mod:`~tasks.clips.importers.floor` (soles onto the floor, what changed and what remains),
  :mod:`~tasks.clips.importers.pipeline` (files in, a clip file out: ``mocap-hierarchy clips import``).
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.clips.importers.pipeline import ImportedClip, import_clip_file, import_motion
    from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError

__all__ = ["ImportedClip", "JointTrajectory", "MotionImportError", "import_clip_file", "import_motion"]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "ImportedClip": "tasks.clips.importers.pipeline",
        "JointTrajectory": "tasks.clips.importers.trajectory",
        "MotionImportError": "tasks.clips.importers.trajectory",
        "import_clip_file": "tasks.clips.importers.pipeline",
        "import_motion": "tasks.clips.importers.pipeline",
    },
)
