"""Study recipes: one module per way of running a study (see :mod:`sim.study`)."""
