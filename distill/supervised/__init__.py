"""The parts of the one supervised loop (:func:`distill.trainer.train` puts them together), one module each.

* :mod:`distill.supervised.checkpoint`: the checkpoint a rerun continues from exactly;
* :mod:`distill.supervised.step`: the optimiser, the clipped step and the stop on a NaN;
* :mod:`distill.supervised.log`: the progress bar, TensorBoard and ``history.json``;
* :mod:`distill.supervised.processes`: the device, the DDP processes and which one writes files.
"""
