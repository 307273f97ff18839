"""The main job on the built-in data: what the shipped skills do, then every stage of the pipeline at small scale.

First, the shipped skills (loaded by name, nothing trained or downloaded; the stages are in
:mod:`mocap_hierarchy.quickstart.shipped`):

- shipped experts: the snippet experts of ``shipped_experts`` (by default the real group
  ``cmu-locomotion-v1``) tracking their snippets under the paper's protocol, some recorded
  (``expert_recordings``);
- shipped go-to-target: the policy on the real decoder ``cmu-v1`` (``shipped_target_policy``)
  read against its targets (the heading verdict), one episode recorded;
- shipped velocity control: the velocity-control policy shipped on ``synthetic-v3``
  (``shipped_velocity_policy``) evaluated on random commanded speeds (the speed-tracking
  verdict), then walked through a sequence of commanded speeds (``demo_speeds``) and recorded;
- shipped motion GPT: ``shipped_gpt`` completing its experts' snippets against two baselines.

Then the pipeline, each stage with a budget far below the shipped skills' (it shows that
every stage runs and learns, not what full budgets reach):

1. clips: the clip library (``clips``: by default ``cmu-locomotion-v1``, real CMU motion shipped with
   the package; ``synthetic`` for the generated clips, or a clip file) and the expert snippets in it (by
   default a real walk, a real 90-degree turn and a real forward jump);
2. playback: roll the fast tracking environment on every expert snippet with the
   open-loop playback controller (the experts' baseline, and the environment's speed);
3. experts: train snippet experts for those snippets (PPO, the paper's
   settings with a small budget; residual actions by default, which start at
   the playback controller's level, see ``experiments/expert_learning.py``), as parallel jobs, and
   evaluate them like the playback rows;
4. dataset: roll the experts out into the rollout dataset (the paper's A.2);
5. distill: the multi-clip policy and its frozen decoder file (the paper's B.2's
   objective; hidden layers shrunk to fit the budget), evaluated against the experts;
6. transfer: velocity control (commands straight ahead below 1.5 m/s by default,
   the speeds the synthetic clips show) trained with PPO on top of a decoder and,
   as the baseline, on raw joint targets, each evaluated deterministically for
   return and commanded against actual speed. The decoder is the shipped
   ``synthetic-v3`` by default, acting around the latent prior shipped with it
   (``transfer_decoder``, ``transfer_prior``; ``own`` takes the one stage 5
   distilled), so the high-level policy rises on skills trained far longer than
   the quickstart can; the summary names both;
7. recordings: both velocity-control policies recorded to ``.rrd`` files;
8. plots: PNG training curves;

then the summary: a table, verdicts in words and ``summary.json``.

A finished stage writes its results to ``out/stages/NAME.json``; a rerun with
the same settings reads them and runs nothing (``distillation: done earlier
(...)``). A stage that was interrupted left no such file: a rerun runs it
again, and the stage resumes its own files (experts marked done, complete
dataset files, the distillation and PPO checkpoints). ``out/stages/runs.json``
lists every run into the folder: when it started, its seconds and the stages it
ran or read.

``--scale`` multiplies every budget (episodes, steps) for real runs. The GPT is
not part of the quickstart (it needs a GPU to learn anything; see the README).

Modules: :mod:`~mocap_hierarchy.quickstart.config` (the settings),
:mod:`~mocap_hierarchy.quickstart.records` (stage records and the run log),
:mod:`~mocap_hierarchy.quickstart.shipped` (the shipped skills' stages),
:mod:`~mocap_hierarchy.quickstart.stages` (each pipeline stage's work; :mod:`~mocap_hierarchy.quickstart.progress`
reads PPO's training returns back),
:mod:`~mocap_hierarchy.quickstart.plots`, :mod:`~mocap_hierarchy.quickstart.verdicts`,
:mod:`~mocap_hierarchy.quickstart.report` (the printed summary) and
:mod:`~mocap_hierarchy.quickstart.pipeline` (:func:`run_quickstart`, which runs them in order).
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from mocap_hierarchy.quickstart.config import EPISODE_LIMIT, QuickstartConfig
    from mocap_hierarchy.quickstart.pipeline import run_quickstart
    from mocap_hierarchy.quickstart.records import (
        RECORD_FORMAT,
        STAGES_DIR,
        RunLog,
        StageRunner,
        digest_of,
        job_runs,
        job_seconds,
        settings_digest,
    )
    from mocap_hierarchy.quickstart.report import print_summary
    from mocap_hierarchy.quickstart.shipped import shipped_velocity_stage
    from mocap_hierarchy.quickstart.verdicts import (
        FOLLOWS_REWARD,
        FOLLOWS_SLOPE,
        HEADS_FOR_TARGETS,
        LEVEL,
        summary_verdicts,
    )

__all__ = [
    "EPISODE_LIMIT",
    "FOLLOWS_REWARD",
    "FOLLOWS_SLOPE",
    "HEADS_FOR_TARGETS",
    "LEVEL",
    "RECORD_FORMAT",
    "STAGES_DIR",
    "QuickstartConfig",
    "RunLog",
    "StageRunner",
    "digest_of",
    "job_runs",
    "job_seconds",
    "print_summary",
    "run_quickstart",
    "settings_digest",
    "shipped_velocity_stage",
    "summary_verdicts",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "EPISODE_LIMIT": "mocap_hierarchy.quickstart.config",
        "FOLLOWS_REWARD": "mocap_hierarchy.quickstart.verdicts",
        "FOLLOWS_SLOPE": "mocap_hierarchy.quickstart.verdicts",
        "HEADS_FOR_TARGETS": "mocap_hierarchy.quickstart.verdicts",
        "LEVEL": "mocap_hierarchy.quickstart.verdicts",
        "RECORD_FORMAT": "mocap_hierarchy.quickstart.records",
        "STAGES_DIR": "mocap_hierarchy.quickstart.records",
        "QuickstartConfig": "mocap_hierarchy.quickstart.config",
        "RunLog": "mocap_hierarchy.quickstart.records",
        "StageRunner": "mocap_hierarchy.quickstart.records",
        "digest_of": "mocap_hierarchy.quickstart.records",
        "job_runs": "mocap_hierarchy.quickstart.records",
        "job_seconds": "mocap_hierarchy.quickstart.records",
        "print_summary": "mocap_hierarchy.quickstart.report",
        "run_quickstart": "mocap_hierarchy.quickstart.pipeline",
        "settings_digest": "mocap_hierarchy.quickstart.records",
        "shipped_velocity_stage": "mocap_hierarchy.quickstart.shipped",
        "summary_verdicts": "mocap_hierarchy.quickstart.verdicts",
    },
)
