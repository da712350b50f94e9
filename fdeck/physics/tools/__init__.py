"""Rigid tool geometry (analytic surfaces)."""
