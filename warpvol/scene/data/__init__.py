"""Data files of the built-in scenes, installed as package data (the nanovdb-cloud scene's grid)."""
