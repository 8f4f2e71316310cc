"""Game layer: referee rules (and the tactics that play)."""
