"""Reusable Qt widgets of StudioTrack (image view with overlays, plots, forms, log panel...).

Widgets may import engine types but never the app (import-linter contract).
"""
