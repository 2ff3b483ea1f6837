"""Bridges to third-party simulators and planners that read our scenario files.

Each bridge is an optional dependency, imported only when its function is called.
"""
