"""The executable of ceco_v2x_preview (setup.py console_scripts), through :func:`ceco_ros.entry.start`."""

from ceco_ros.entry import start


def preview_node() -> int:
    """The preview_node executable."""
    return start('ceco_v2x_preview.preview_node', 'preview_node')
