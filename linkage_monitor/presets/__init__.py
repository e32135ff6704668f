"""Bundled mechanism presets (YAML, one per seed paper); list and load them with
``linkage_monitor.mechanics.preset_names()`` / ``load_preset(name)``."""
