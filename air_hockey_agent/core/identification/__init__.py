"""System identification from recordings: preprocessing, HEBO sysid, noise estimation (thesis 4.3-4.5)."""
