"""The stand-in's ``rps.utilities``."""
