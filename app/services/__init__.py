"""Thin adapters between the HTTP layer / CLI and the engine (no physics or numerics here)."""
