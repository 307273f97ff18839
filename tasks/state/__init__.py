"""Environment state as plain data: snapshots of a walker task and of a whole SB3 ``VecEnv`` chain.

* :mod:`tasks.state.env_state`: the shared pieces of every environment's ``get_state``/``set_state``
  (MuJoCo's integration state, ``np_random``, the episode in progress), ``get_env_state`` through wrappers,
  and :class:`~tasks.state.env_state.StateWrapper`;
* :mod:`tasks.state.vec_env_state`: a whole SB3 ``VecEnv`` chain, its normaliser and wrappers and each
  environment, in-process or in worker processes.
"""
