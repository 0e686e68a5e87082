"""OUT/sweep.png: per controller, distance and contacts across seeds (one line per world and robot count)."""
from __future__ import annotations

from typing import BinaryIO

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402 - after choosing the file backend
from matplotlib.ticker import MaxNLocator  # noqa: E402


def draw_sweep(rows: list[dict], out: BinaryIO) -> None:
    """Two rows of panels (distance, contacts), a column per controller; a robot's row is a point at its seed."""
    good = [row for row in rows if not row['error']]
    controllers = sorted({row['controller'] for row in good}) or ['(no trial ran)']
    figure, axes = plt.subplots(2, len(controllers), figsize=(4.5 * len(controllers) + 1, 6.5), squeeze=False,
                                sharex='col')
    for column, controller in enumerate(controllers):
        mine = [row for row in good if row['controller'] == controller]
        for world, robots in sorted({(row['world'], row['robots']) for row in mine}):
            group = [row for row in mine if (row['world'], row['robots']) == (world, robots)]
            seeds = [int(row['seed']) for row in group]
            label = f'{world}, {robots} robot(s)'
            axes[0][column].plot(seeds, [float(row['distance_m']) for row in group], 'o', alpha=0.7, label=label)
            contacts = [int(row['contacts_obstacles']) + int(row['contacts_robots']) for row in group]
            axes[1][column].plot(seeds, contacts, 's', alpha=0.7, label=label)
        axes[0][column].set_title(controller, fontsize=11)
        axes[0][column].set_ylabel('distance (m)')
        axes[1][column].set_ylabel('contacts')
        axes[1][column].set_xlabel('seed')
        for axis in axes[:, column]:
            axis.grid(True, alpha=0.3)
            axis.xaxis.set_major_locator(MaxNLocator(integer=True))
        axes[1][column].yaxis.set_major_locator(MaxNLocator(integer=True))
        most = max((int(row['contacts_obstacles']) + int(row['contacts_robots']) for row in mine), default=0)
        axes[1][column].set_ylim(-0.5, max(most, 1) + 0.5)   # whole contacts from 0, even when there were none
        if mine:
            axes[0][column].legend(fontsize=8)
    failed = len({row['trial'] for row in rows if row['error']})
    figure.suptitle(f'sweep: {len({row["trial"] for row in rows})} trials' + (f', {failed} failed' if failed else ''))
    figure.tight_layout()
    figure.savefig(out, format='png', dpi=100)
    plt.close(figure)
