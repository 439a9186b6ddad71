"""Implementations of the `gcs` sub-commands (called by groundstation.cli)."""
