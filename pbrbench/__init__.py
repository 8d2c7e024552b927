"""pbrbench: a physically based rendering testbed for light-and-shading vision problems.

Data flows one way: scene file -> ground truth (Mitsuba 3) -> algorithm inputs ->
inference (:mod:`pbrbench.infer`, pure NumPy/SciPy) -> scores (:mod:`pbrbench.metrics`)
-> results store and HTML report.
"""

__version__ = "0.1.0"
