"""V2X weather and traffic preview publisher and the scenario files for ceco.

Scenario files hold drive cycles, weather, occupant and comfort bounds.
"""
