"""
Recordings of other sources (a real axis's rosbag2 bag): mapped onto the model's inputs and states.

:mod:`.mapping` turns the options (or a ``--map`` YAML file) into a
:class:`~.mapping.Mapping`; :mod:`.states` reads the mapped JointState
states by their header stamps; :mod:`.commands` decodes and samples the
command types on the step grid; :mod:`.delay` estimates the constant
command-to-state delay; :mod:`.replay` re-simulates the commands
(:class:`~.replay.ForeignReplay`); :mod:`.twin` compares the measured
states with the twin's (:func:`~.twin.twin_comparison`).
"""
