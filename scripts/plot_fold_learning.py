#!/usr/bin/env python3
"""Plots of a fold_learner run: reads DIR/epochs.csv, DIR/coordination.csv and DIR/summary.json, writes
DIR/learning_curve.png (mean reward of each epoch's rollouts per algorithm: the mean over runs, with the rollouts'
standard deviation as a band, and the reward terms), DIR/coordination.png (the final coordination matrices, thesis
Fig. 7.9d) and DIR/table75.md (the measured Table 7.5 next to the thesis').

Usage: plot_fold_learning.py DIR
"""
import csv
import json
import math
import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from plot_common import output_directory  # noqa: E402

# Thesis Table 7.5: mean reward of the rollouts at epoch 1 and epoch 15 (3 runs).
THESIS_75 = {'DR-DMP0(12)': (-2.47, -1.14), 'IDR-DMP_CMU': (-2.48, -0.91), 'IDR-DMP_MCMU(3)': (-2.57, -1.00)}
DOF_NAMES = ['L x', 'L y', 'L z', 'L v1', 'L v2', 'L v3', 'R x', 'R y', 'R z', 'R v1', 'R v2', 'R v3']


def read_epochs(path):
    by = defaultdict(lambda: defaultdict(list))
    with open(path) as f:
        for row in csv.DictReader(f):
            by[row['algorithm']][int(row['epoch'])].append(row)
    return by


def learning_curve(directory, epochs):
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for algorithm, per_epoch in epochs.items():
        xs = sorted(per_epoch)
        mean = [sum(float(r['mean_reward']) for r in per_epoch[e]) / len(per_epoch[e]) for e in xs]
        std = [sum(float(r['std_reward']) for r in per_epoch[e]) / len(per_epoch[e]) for e in xs]
        line, = axes[0].plot(xs, mean, marker='o', label=algorithm)
        axes[0].fill_between(xs, [m - s for m, s in zip(mean, std)], [m + s for m, s in zip(mean, std)],
                             color=line.get_color(), alpha=0.2)
        for term, style in (('r_acceleration', ':'), ('r_color', '--'), ('r_depth', '-.')):
            values = [sum(float(r[term]) for r in per_epoch[e]) / len(per_epoch[e]) for e in xs]
            axes[1].plot(xs, values, style, color=line.get_color(), label=f'{algorithm} {term}')
    axes[0].set_xlabel('epoch (policy updates)')
    axes[0].set_ylabel('reward (7.52)')
    axes[0].set_title('Mean reward of the rollouts (band: their std)')
    axes[0].grid(True, alpha=0.3)
    axes[0].legend()
    axes[1].set_xlabel('epoch (policy updates)')
    axes[1].set_ylabel('penalty')
    axes[1].set_title('Reward terms (mean over the rollouts that finished)')
    axes[1].grid(True, alpha=0.3)
    axes[1].legend(fontsize=7)
    for ax in axes:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'learning_curve.png'), dpi=100)
    plt.close(fig)


def coordination(directory):
    path = os.path.join(directory, 'coordination.csv')
    if not os.path.exists(path):
        return
    matrices = defaultdict(lambda: defaultdict(list))
    with open(path) as f:
        reader = csv.reader(f)
        next(reader)
        for row in reader:
            if row[1] != '0':
                continue  # the first run of each algorithm
            matrices[row[0]][int(row[2])].append([float(v) for v in row[4:]])
    panels = [(a, s, m) for a, per in matrices.items() for s, m in sorted(per.items())]
    if not panels:
        return
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 4.2), squeeze=False)
    for ax, (algorithm, s, m) in zip(axes[0], panels):
        limit = max(abs(v) for row in m for v in row) or 1.0
        image = ax.imshow(m, cmap='RdBu_r', vmin=-limit, vmax=limit)
        ax.set_title(f'{algorithm}\nOmega_{s + 1}: 12 x {len(m[0])}', fontsize=9)
        ax.set_yticks(range(len(DOF_NAMES)))
        ax.set_yticklabels(DOF_NAMES, fontsize=7)
        ax.set_xlabel('latent DoF')
        fig.colorbar(image, ax=ax, fraction=0.046)
    fig.suptitle('Final coordination matrices (first run)')
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'coordination.png'), dpi=100)
    plt.close(fig)


def table(directory, epochs):
    summary = json.load(open(os.path.join(directory, 'summary.json')))
    lines = ['| algorithm | runs | first epoch (ours) | after the last update (ours) | final r | thesis epoch 1 | '
             'thesis epoch 15 |',
             '|---|---|---|---|---|---|---|']
    for algorithm, per_epoch in epochs.items():
        rows = [r for r in summary['results'] if r.get('experiment') == 'fold' and r['algorithm'] == algorithm]
        rows.sort(key=lambda r: r['epoch'])
        first = rows[0]
        last = rows[-1]
        thesis = THESIS_75.get(algorithm, (math.nan, math.nan))
        lines.append(f"| {algorithm} | {last['runs']} | {first['mean_reward']:.3f} ± {first['std_reward']:.3f} | "
                     f"{last['mean_reward']:.3f} ± {last['std_reward']:.3f} ({last['epoch']} updates) | "
                     f"{last['latent_dims']:.0f} | {thesis[0]} | {thesis[1]} |")
    for r in summary['results']:
        if r.get('experiment') == 'repetitions':
            lines.append('')
            lines.append(f"Initial policy over {r['repetitions']} noise-free repetitions: R = {r['mean_reward']:.3f} ± "
                         f"{r['std_reward']:.3f}, rho = {r['fill_ratio']:.3f} ± {r['fill_ratio_std']:.3f}, "
                         f"gbar = {r['mean_gradient']:.3f} ± {r['mean_gradient_std']:.3f} (thesis: R_color 0.799 ± "
                         f"0.088, R_depth 0.473 ± 0.029)")
    with open(os.path.join(directory, 'table75.md'), 'w') as f:
        f.write('\n'.join(lines) + '\n')


def main():
    directory = output_directory(__doc__)
    epochs = read_epochs(os.path.join(directory, 'epochs.csv'))
    learning_curve(directory, epochs)
    coordination(directory)
    table(directory, epochs)
    print(f'plot_fold_learning: wrote {directory}/learning_curve.png, coordination.png, table75.md')


if __name__ == '__main__':
    main()
