"""Scripted sample scenes (the valley, Mars): the CLI builds them by name; they ship in the extension."""
