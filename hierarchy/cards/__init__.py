"""Model cards, one home: the card's JSON, the renderer, its sections and the builders of the hierarchy's files.

* :mod:`hierarchy.cards.model_card`: the card's JSON, its fields' types checked, and how it is attached to a file;
* :mod:`hierarchy.cards.page`: the one renderer (``card_page``) and the builders' registry, by file format;
* :mod:`hierarchy.cards.markdown`: the eight sections, file facts, tables and links every builder uses;
* :mod:`hierarchy.cards.decoder`, :mod:`hierarchy.cards.latent_prior`, :mod:`hierarchy.cards.task_policy`: the
  builders of a decoder's, a latent prior's and a task policy's card.

The builders of files from a floor above (snippet experts, motion GPTs) are in :mod:`distill.cards` and register
themselves here on import.
"""
