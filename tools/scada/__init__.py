"""Real measured SCADA records (docs/real-data.md): column maps, the reader, its bad-row rules and counters, and the
linear normal-behaviour model (NBM) the physics is compared against."""
