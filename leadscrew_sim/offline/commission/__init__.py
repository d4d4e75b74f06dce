"""The run library of ``leadscrew_sim commission``: one recording, the axis's report."""
