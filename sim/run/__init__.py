"""One run: the scenario, its timeline (simpy schedule), the streaming simulator and its budget."""
