"""Drawings and plots (PNG) and, later, rerun recordings."""
