"""Cabin and A/C plant simulation and ISO 7730 PMV comfort for ceco.

The plant is a lumped thermal network with a vapour-compression cycle (CoolProp).
"""
