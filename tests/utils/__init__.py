"""Helpers the test packages share (import from here, never from another test module)."""
