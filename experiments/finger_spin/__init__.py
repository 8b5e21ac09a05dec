"""Gentleness on dm_control's finger-spin: ``grid.sh`` runs ``finger_spin.yaml``."""
