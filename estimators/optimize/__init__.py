"""Population optimisers for hyper-parameter tuning: Harris hawks (HHO) and particle swarm (PSO).

Both minimise a vectorised fitness over a box, are reproducible from ``random_state``, accept an
evaluation budget and report the evaluation count and the best-so-far curve
(:class:`OptimizeResult`).
"""

from rlgsim.estimators.optimize.hho import harris_hawks
from rlgsim.estimators.optimize.pso import particle_swarm
from rlgsim.estimators.optimize.result import OptimizeResult

__all__ = ["OptimizeResult", "harris_hawks", "particle_swarm"]
