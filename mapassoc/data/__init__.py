"""Data in and out: scans, the CSV tables, the TOML configuration and the settings it
holds.
"""
