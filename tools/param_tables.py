"""Print the parameter tables of every ceco node (docs/ros.md), generated from the nodes' ParamSpec tables.

    python tools/param_tables.py            # print them
    python tools/param_tables.py --write    # rewrite the marked blocks in docs/ros.md

Each block in docs/ros.md sits between ``<!-- params:<node> -->`` and ``<!-- /params -->``;
tests/test_node_logic.py checks that the document holds exactly these tables.
"""

from __future__ import annotations

import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
for pkg in ('ceco_core', 'ceco_ros', 'ceco_v2x_preview', 'ceco_plant_sim', 'ceco_controller'):
    sys.path.insert(0, str(ROOT / pkg))


def tables() -> dict[str, str]:
    from ceco_controller.controller_io import controller_parameters
    from ceco_plant_sim.plant_io import PLANT_PARAMETERS
    from ceco_ros.params import markdown_table
    from ceco_v2x_preview.preview_io import PREVIEW_PARAMETERS

    return {
        'mpc_node': markdown_table(controller_parameters()),
        'baseline_node': markdown_table(controller_parameters('baseline')),
        'plant_node': markdown_table(PLANT_PARAMETERS),
        'preview_node': markdown_table(PREVIEW_PARAMETERS),
    }


def rewrite(text: str) -> str:
    for node, table in tables().items():
        text = re.sub(
            rf'(<!-- params:{node} -->\n).*?(<!-- /params -->)',
            lambda m, t=table: m[1] + t + '\n' + m[2],
            text,
            flags=re.S,
        )
    return text


if __name__ == '__main__':
    if '--write' in sys.argv:
        doc = ROOT / 'docs' / 'ros.md'
        doc.write_text(rewrite(doc.read_text()))
    else:
        for node, table in tables().items():
            print(f'### {node}\n\n{table}\n')
