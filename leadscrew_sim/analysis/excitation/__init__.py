"""Excitation profiles: the command sequences `excite` sends, with defaults from the axis."""
