"""Real motion shipped with the library: CMU trials converted onto the walker, loadable by name.

:mod:`tasks.clips.real.library` holds the names (``cmu-locomotion-v1``), the packaged joint
trajectories and their expansion into a clip file every command reads.
"""
