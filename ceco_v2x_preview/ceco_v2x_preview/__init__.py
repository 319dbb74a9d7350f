"""V2X weather and traffic preview publisher and the scenario files (drive cycles, weather, occupant, comfort bounds) for ceco."""
