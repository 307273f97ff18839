"""Producers and consumers of the expert-rollout dataset (experts, rollouts, NPMP, GPT).

Empty until the experts/dataset issue lands.
"""
