"""Training of the learned parts, above the engine and the evaluation.

:mod:`ftnav.training.detector`: paper 000's RBF fault detector (spec §4);
:mod:`ftnav.training.fusion`: paper 001's neuron fusion centre on a linear system
(spec §5); :mod:`ftnav.training.ins_fusion`: the same on the SINS error model of an
integrated scenario.  Each runs the engine on simulated streams with the true fault
windows and saves nothing itself (:mod:`ftnav.io.learned` writes the model files).
"""
