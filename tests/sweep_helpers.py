"""A sweep's log row as the tests write it by hand (``ceco_bringup.sweep``: one row per cell)."""


def sweep_row(scenario: str, strategy: str, *, settings: str = 'default', seed: int = 0, **metrics) -> dict:
    """A finished cell's row: the grid's axes (the other axes at 'scenario' / 'perfect') and ``metrics``."""
    return {
        'status': 'ok',
        'scenario': scenario,
        'drive_cycle': 'scenario',
        'climate': 'scenario',
        'preview': 'perfect',
        'occupant': 'scenario',
        'seed': seed,
        'strategy': strategy,
        'settings': settings,
        **metrics,
    }
