"""The one catalogue of everything shipped with the library: what a name is, of every kind.

Each kind keeps its folder in its own package (read at each call, so tests can point one
elsewhere) and its loader keeps resolving its own names (an existing path wins); this module
puts the kinds together once, in :data:`KINDS` order, for whatever takes a name of several
kinds (``mocap-hierarchy record --policy NAME``), for ``mocap-hierarchy models`` and for the
site's model pages. It lives on the ``distill`` floor, the lowest that sees every kind's folder.

Names are unique within a kind, not across kinds: ``synthetic-v3`` is a decoder, a latent prior,
an expert group and a motion GPT, and a multi-clip policy is named after the decoder it contains.
Whoever looks a name up says which kinds it means, and the first of them in :data:`KINDS` order wins
(:data:`POLICY_KINDS`: a decoder before a multi-clip policy before a task policy before an expert
before an expert group), but on the tracking task, where a multi-clip policy tracks the clip and its
decoder would act at random, the multi-clip policy of a name comes first (:data:`TRACKING_POLICY_KINDS`).
"""

from __future__ import annotations

from foundation.shipped import Catalogue

KINDS = (
    "decoder",
    "multi-clip policy",
    "task policy",
    "expert",
    "expert group",
    "latent prior",
    "motion GPT",
    "joint map",
    "clip library",
)
"""Every kind of shipped artifact, in the order that settles a name several kinds share."""

POLICY_KINDS = ("decoder", "multi-clip policy", "task policy", "expert", "expert group")
"""The kinds ``record --policy NAME`` takes by name, in the order it tries them (a GPT only as a file)."""

TRACKING_POLICY_KINDS = ("multi-clip policy", "decoder", "task policy", "expert", "expert group")
"""The order ``record --task tracking --policy NAME`` tries them: a multi-clip policy before the decoder it contains."""

POLICY_HINT_KINDS = ("decoder", "multi-clip policy", "task policy", "expert")
"""The kinds whose names ``record`` lists for an unknown policy (the experts' list names their groups too)."""


def catalogue() -> Catalogue:
    """The shipped artifacts of this installation, read from the package folders now."""
    from distill.experts.shipped import expert_group_shelf, expert_shelf
    from distill.gpt.shipped import gpt_shelf
    from distill.npmp.shipped import policy_shelf
    from hierarchy.latent_prior import prior_shelf
    from hierarchy.pretrained import shipped_decoders, task_policy_shelf
    from tasks.clips.importers.joint_map import shipped_joint_maps
    from tasks.clips.real.library import clip_library_shelf

    shelves = (
        shipped_decoders(),
        policy_shelf(),
        task_policy_shelf(),
        expert_shelf(),
        expert_group_shelf(),
        prior_shelf(),
        gpt_shelf(),
        shipped_joint_maps(),
        clip_library_shelf(),
    )
    assert tuple(shelf.kind for shelf in shelves) == KINDS
    return Catalogue(shelves)
