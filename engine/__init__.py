"""StudioTrack engine: tracking, sources, evaluation and outputs. Imports no Qt."""
