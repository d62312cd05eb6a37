"""Scripted sample scenes (not part of the extension zip)."""
