"""``play``'s library: the playback schedule and serving a recording to Foxglove."""
