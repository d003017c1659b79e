"""Population optimisers for hyper-parameter tuning: Harris hawks (HHO) and particle swarm (PSO).

Both minimise a vectorised fitness over a box, are reproducible from ``random_state``, accept an
evaluation budget and report the evaluation count and the best-so-far curve
(:class:`OptimizeResult`).
"""

from .hho import harris_hawks
from .pso import particle_swarm
from .result import OptimizeResult

__all__ = ["OptimizeResult", "harris_hawks", "particle_swarm"]
