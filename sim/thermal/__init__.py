"""The thermal side of the simulator: the network, its exact integrator, the chamber and its controller, the thermometers."""
