"""The card builders of the hierarchy's own files, one module per file format.

* :mod:`hierarchy.card_builders.decoder`: a decoder file's card;
* :mod:`hierarchy.card_builders.latent_prior`: a latent prior file's card;
* :mod:`hierarchy.card_builders.task_policy`: a task policy file's card.

:mod:`hierarchy.card_page` picks the builder by the file's format and renders its page;
the parts every builder uses are in :mod:`hierarchy.card_markdown`.
"""
