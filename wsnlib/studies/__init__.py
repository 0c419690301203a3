"""Studies: the computations behind the notebooks, one module per study.

A notebook calls one study function per result; the study calls the library's algorithms
(:mod:`wsnlib.orientation`, :mod:`wsnlib.radio`, :mod:`wsnlib.posture`, ...), the
simulators (:mod:`wsnlib.sim`) and the loaders (:mod:`wsnlib.io`), and returns arrays and
tables; :mod:`wsnlib.plotting` draws them.  Nothing below the studies imports them.
"""
