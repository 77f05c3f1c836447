"""Files a run writes: atomic JSON and CSV, the one-writer folder lock, provenance."""
