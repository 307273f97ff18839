"""The card builders of the files the floors keep out of :mod:`hierarchy.cards`: experts, GPTs, multi-clip policies.

Their files and names live in :mod:`distill` (:mod:`distill.experts` never imports the high-level side, so its
card cannot live beside it); the renderer, the sections and the registry are :mod:`hierarchy.cards`'. Importing
this package registers every builder, so :func:`hierarchy.cards.page.card_page` then renders their files too.

* :mod:`distill.cards.expert`: an expert's ``expert.safetensors`` (``mocap-hierarchy expert card``);
* :mod:`distill.cards.gpt`: a motion GPT file (``mocap-hierarchy gpt card``);
* :mod:`distill.cards.multi_clip`: a multi-clip policy file (``mocap-hierarchy distill card``).
"""

from distill.cards import expert, gpt, multi_clip

__all__ = ["expert", "gpt", "multi_clip"]
