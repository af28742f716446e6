"""Scenes: the TOML schema, loading, the resolved run configuration, validation before work, caveats, and the
effect set.
"""
