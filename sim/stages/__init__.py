"""The stages of the simulator's block loop: where the models meet the dataset schema
(:mod:`rlgsim.sim.stages.base` is the interface, :mod:`rlgsim.sim.stages.registry` the list)."""
