"""Cabin and A/C plant simulation (lumped thermal network, vapour-compression cycle with CoolProp) and ISO 7730 PMV comfort for ceco."""
