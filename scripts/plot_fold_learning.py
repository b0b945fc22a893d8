#!/usr/bin/env python3
"""Plots of a fold_learner run: reads DIR/epochs.csv, DIR/coordination.csv and DIR/summary.json, writes
DIR/learning_curve.png (per algorithm and epoch, the mean over runs of the rollouts' mean reward with their standard
deviation as a band, the reward terms, and the fold quality q from the cloth mesh), DIR/coordination.png (the final
coordination matrices, thesis Fig. 7.9d) and DIR/table75.md (the measured Table 7.5 next to the thesis'); and, from
DIR/NAME_frames.csv, NAME_triangles.csv and NAME_top_K.png that fold_learner writes for the initial and the final
policy, DIR/filmstrip_NAME.png (six moments: the top-down camera above, an oblique view below, q under each) and
DIR/NAME.gif (the oblique view of the whole rollout).

Usage: plot_fold_learning.py DIR
"""
import csv
import json
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from PIL import Image  # noqa: E402
from plot_common import mean_ci, output_directory  # noqa: E402
from scipy import stats  # noqa: E402

# Thesis Table 7.5: mean reward of the rollouts at epoch 1 and epoch 15 (3 runs).
THESIS_75 = {'DR-DMP0(12)': (-2.47, -1.14), 'IDR-DMP_CMU': (-2.48, -0.91), 'IDR-DMP_MCMU(3)': (-2.57, -1.00)}
# The fold quality a policy should reach (issue target), and the reward signals compared with q.
Q_TARGET = 0.8
# Each as a function of a rollouts.csv row and the acceleration cost A = int |qdd|^2 dt (the run's R_acceleration
# over its w_a), whatever reward the run learned on: the two named reward settings and their terms.
PROXY_SIGNALS = [
    ('thesis reward (7.52)', lambda r, a: -0.01 * a - (1.0 - float(r['fill_ratio'])) - float(r['mean_gradient'])),
    ('goal reward', lambda r, a: -0.002 * a - float(r['goal_mismatch'])),
    ('-R_acceleration', lambda r, a: -a),
    ('-R_color (1 - rho)', lambda r, a: float(r['fill_ratio']) - 1.0),
    ('-R_depth (gbar)', lambda r, a: -float(r['mean_gradient'])),
    ('-goal mismatch', lambda r, a: -float(r['goal_mismatch']))]
DOF_NAMES = ['L x', 'L y', 'L z', 'L v1', 'L v2', 'L v3', 'R x', 'R y', 'R z', 'R v1', 'R v2', 'R v3']


def read_epochs(path):
    by = defaultdict(lambda: defaultdict(list))
    with open(path) as f:
        for row in csv.DictReader(f):
            by[row['algorithm']][int(row['epoch'])].append(row)
    return by


def band(rows, column, spread):
    """Mean of `column` over the runs of an epoch and its band: the 95 % Student-t interval of that mean when there
    are several runs, else the rollouts' own standard deviation (`spread`)."""
    values = [float(r[column]) for r in rows]
    if len(values) > 1:
        return mean_ci(values)
    return values[0], float(rows[0][spread])


def learning_curve(directory, epochs):
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.5))
    runs = max(len(rows) for per_epoch in epochs.values() for rows in per_epoch.values())
    band_name = f'95 % t-interval over {runs} runs' if runs > 1 else 'the rollouts\' std'
    for algorithm, per_epoch in epochs.items():
        xs = sorted(per_epoch)
        reward = [band(per_epoch[e], 'mean_reward', 'std_reward') for e in xs]
        line, = axes[0].plot(xs, [m for m, _ in reward], marker='o', label=algorithm)
        axes[0].fill_between(xs, [m - d for m, d in reward], [m + d for m, d in reward], color=line.get_color(),
                             alpha=0.2)
        for term, style in (('r_acceleration', ':'), ('r_color', '--'), ('r_depth', '-.'), ('r_goal', '-')):
            values = [sum(float(r[term]) for r in per_epoch[e]) / len(per_epoch[e]) for e in xs]
            if any(values):  # a term the reward setting weighs by 0 is left out
                axes[1].plot(xs, values, style, color=line.get_color(), label=f'{algorithm} {term}')
        q = [band(per_epoch[e], 'fold_quality', 'fold_quality_std') for e in xs]
        axes[2].plot(xs, [m for m, _ in q], marker='o', color=line.get_color(), label=algorithm)
        axes[2].fill_between(xs, [m - d for m, d in q], [m + d for m, d in q], color=line.get_color(), alpha=0.2)
    axes[0].set_xlabel('epoch (policy updates)')
    axes[0].set_ylabel(f'reward ({reward_setting(directory)} setting)')
    axes[0].set_title(f'Mean reward of the rollouts (band: {band_name})')
    axes[0].grid(True, alpha=0.3)
    axes[0].legend()
    axes[1].set_xlabel('epoch (policy updates)')
    axes[1].set_ylabel('penalty')
    axes[1].set_title('Reward terms (mean over the rollouts that finished)')
    axes[1].grid(True, alpha=0.3)
    axes[1].legend(fontsize=7)
    axes[2].set_xlabel('epoch (policy updates)')
    axes[2].set_ylabel('fold quality q (1: ideal fold, 0: flat)')
    axes[2].set_title(f'Fold quality q from the cloth mesh (band: {band_name})', fontsize=10)
    axes[2].grid(True, alpha=0.3)
    axes[2].legend()
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


def read_rollouts(directory):
    with open(os.path.join(directory, 'rollouts.csv')) as f:
        return list(csv.DictReader(f))


def interval(values):
    m, d = mean_ci(values)
    return f'{m:.3f} ± {d:.3f}' if len(values) > 1 else f'{m:.3f}'


def table(directory, epochs, rollouts):
    """table75.md: per algorithm, the rollouts' mean reward and fold quality at a few epochs (mean ± 95 % t-interval
    over the runs), Welch's test between the algorithms at the last epoch, Spearman's rho between the camera reward,
    its terms and q over every rollout, and the rollouts each run needed to reach q >= Q_TARGET."""
    summary = json.load(open(os.path.join(directory, 'summary.json')))
    last = min(max(per_epoch) for per_epoch in epochs.values())
    shown = sorted({0, min(5, last), min(10, last), last})
    lines = []
    for column, title in (('mean_reward', f'Mean reward ({reward_setting(directory)} setting) of the rollouts'),
                          ('fold_quality', 'Fold quality q of the rollouts (cloth mesh)')):
        lines += [f'{title}: mean ± 95 % Student-t interval over the runs (one value per run: the mean of its '
                  'rollouts at that epoch)', '',
                  '| algorithm | runs | ' + ' | '.join(f'epoch {e}' for e in shown) + ' | final r |' +
                  (' thesis epoch 1 → 15 |' if column == 'mean_reward' else ''),
                  '|---|---:|' + '---:|' * (len(shown) + 1) + ('---|' if column == 'mean_reward' else '')]
        for algorithm, per_epoch in epochs.items():
            cells = [interval([float(r[column]) for r in per_epoch[e]]) for e in shown]
            dims = sum(float(r['latent_dims']) for r in per_epoch[last]) / len(per_epoch[last])
            thesis = THESIS_75.get(algorithm)
            extra = (f' {thesis[0]} → {thesis[1]} |' if thesis else ' |') if column == 'mean_reward' else ''
            lines.append(f'| {algorithm} | {len(per_epoch[last])} | ' + ' | '.join(cells) + f' | {dims:.1f} |' + extra)
        lines.append('')
    names = list(epochs)
    if len(names) > 1:
        lines += [f'Welch\'s t-test at epoch {last} (two-sided; difference of the first minus the second):', '',
                  '| pair | reward difference | p | q difference | p |', '|---|---:|---:|---:|---:|']
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                cells = []
                for column in ('mean_reward', 'fold_quality'):
                    x = [float(r[column]) for r in epochs[a][last]]
                    y = [float(r[column]) for r in epochs[b][last]]
                    p = stats.ttest_ind(x, y, equal_var=False).pvalue if min(len(x), len(y)) > 1 else math.nan
                    cells += [f'{np.mean(x) - np.mean(y):+.3f}', f'{p:.3f}']
                lines.append(f'| {a} vs {b} | ' + ' | '.join(cells) + ' |')
        lines.append('')
    finished = [r for r in rollouts if r['outcome'] == 'Ok' and r['kind'] == 'sample']
    if len(finished) > 2:
        q = [float(r['fold_quality']) for r in finished]
        lines += [f'Is the camera reward a proxy of the fold? Spearman\'s rho with q over the {len(finished)} finished '
                  'rollouts (penalties negated, so a good proxy has rho near 1):', '',
                  '| signal | rho | p |', '|---|---:|---:|']
        weight = acceleration_weight(directory)
        for label, signal in PROXY_SIGNALS:
            rho, p = stats.spearmanr([signal(r, float(r['r_acceleration']) / weight) for r in finished], q)
            lines.append(f'| {label} | {rho:.3f} | {p:.1e} |')
        lines.append('')
        proxy_scatter(directory, finished, weight)
    lines += [f'Rollouts to reach q ≥ {Q_TARGET} (the first epoch whose rollouts\' mean q reaches it; all rollouts up '
              'to and including it):', '',
              '| algorithm | runs | reached | median rollouts | range | best epoch mean q (mean over runs) |',
              '|---|---:|---:|---:|---|---:|']
    for algorithm, per_epoch in epochs.items():
        needed = rollouts_to_target(algorithm, per_epoch, rollouts)
        reached = sorted(n for n in needed if n is not None)
        best = [max(float(r['fold_quality']) for e in per_epoch for r in per_epoch[e] if int(r['run']) == run)
                for run in sorted({int(r['run']) for rows in per_epoch.values() for r in rows})]
        median = np.median([n if n is not None else math.inf for n in needed])
        median = 'never' if math.isinf(median) else f'{median:.0f}'
        span = f'{reached[0]}–{reached[-1]}' if reached else '–'
        lines.append(f'| {algorithm} | {len(needed)} | {len(reached)} | {median} | {span} | '
                     f'{np.mean(best):.3f} |')
    for r in summary['results']:
        if r.get('experiment') == 'repetitions':
            lines.append('')
            lines.append(f"Initial policy over {r['repetitions']} noise-free repetitions: R = {r['mean_reward']:.3f} ± "
                         f"{r['std_reward']:.3f}, rho = {r['fill_ratio']:.3f} ± {r['fill_ratio_std']:.3f}, "
                         f"gbar = {r['mean_gradient']:.3f} ± {r['mean_gradient_std']:.3f} (thesis: R_color 0.799 ± "
                         f"0.088, R_depth 0.473 ± 0.029; std over the repetitions)")
    with open(os.path.join(directory, 'table75.md'), 'w') as f:
        f.write('\n'.join(lines) + '\n')


def rollouts_to_target(algorithm, per_epoch, rollouts):
    """Per run, the number of sampled rollouts up to the first epoch whose mean q reaches Q_TARGET (None: never)."""
    needed = []
    for run in sorted({int(r['run']) for rows in per_epoch.values() for r in rows}):
        reached = [e for e in sorted(per_epoch) for r in per_epoch[e]
                   if int(r['run']) == run and float(r['fold_quality']) >= Q_TARGET]
        if not reached:
            needed.append(None)
            continue
        needed.append(sum(1 for r in rollouts if r['algorithm'] == algorithm and int(r['run']) == run
                          and r['kind'] == 'sample' and int(r['epoch']) <= reached[0]))
    return needed


def reward_file(directory):
    """The run's reward setting and weights (reward.txt)."""
    with open(os.path.join(directory, 'reward.txt')) as f:
        return dict(line.split() for line in f if line.strip())


def reward_setting(directory):
    return reward_file(directory)['setting']


def acceleration_weight(directory):
    """w_a of the run's reward, by which its R_acceleration column is weighted."""
    weight = float(reward_file(directory)['acceleration_weight'])
    if weight <= 0.0:
        sys.exit(f'plot_fold_learning: {directory} learned with acceleration_weight 0: the acceleration cost is lost')
    return weight


def proxy_scatter(directory, finished, weight):
    columns = (len(PROXY_SIGNALS) + 1) // 2
    fig, axes = plt.subplots(2, columns, figsize=(4.2 * columns, 8))
    axes = axes.ravel()
    q = np.array([float(r['fold_quality']) for r in finished])
    for ax, (label, signal) in zip(axes, PROXY_SIGNALS):
        x = np.array([signal(r, float(r['r_acceleration']) / weight) for r in finished])
        for algorithm in sorted({r['algorithm'] for r in finished}):
            mask = np.array([r['algorithm'] == algorithm for r in finished])
            ax.scatter(x[mask], q[mask], s=6, alpha=0.5, label=algorithm)
        rho = stats.spearmanr(x, q)[0]
        ax.set_title(f'{label}: Spearman rho = {rho:.2f}', fontsize=10)
        ax.set_xlabel(label)
        ax.set_ylabel('fold quality q')
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7, markerscale=2)
    fig.suptitle('The camera reward and its terms against the fold quality from the cloth mesh, every rollout')
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'proxy.png'), dpi=100)
    plt.close(fig)


def read_frames(directory, name):
    """The rollout's cloth frames (time, q, 3 x N nodes) and triangles, or None when fold_learner wrote none."""
    path = os.path.join(directory, f'{name}_frames.csv')
    if not os.path.exists(path):
        return None
    times, qualities, meshes = [], [], []
    with open(path) as f:
        next(f)
        for line in f:
            values = [float(v) for v in line.split(',')]
            times.append(values[0])
            qualities.append(values[1])
            meshes.append(np.array(values[2:]).reshape(-1, 3))
    with open(os.path.join(directory, f'{name}_triangles.csv')) as f:
        next(f)
        triangles = np.array([[int(v) for v in line.split(',')] for line in f])
    return times, qualities, meshes, triangles


def draw_oblique(ax, mesh, triangles, q, t):
    """The cloth seen from the front left and above, its triangles shaded by height."""
    polygons = mesh[triangles]
    heights = polygons[:, :, 2].mean(axis=1)
    collection = Poly3DCollection(polygons, facecolors=plt.cm.viridis(np.clip((heights - 0.15) / 0.25, 0, 1)),
                                  edgecolors='none')
    ax.add_collection3d(collection)
    ax.set_xlim(0.2, 0.8)
    ax.set_ylim(-0.35, 0.35)
    ax.set_zlim(0.1, 0.5)
    ax.view_init(elev=30, azim=-120)
    ax.set_axis_off()
    ax.set_title(f't = {t:.1f} s, q = {q:.2f}', fontsize=9)


def filmstrip(directory, name):
    frames = read_frames(directory, name)
    if frames is None:
        return False
    times, qualities, meshes, triangles = frames
    last = len(meshes) - 1
    fig = plt.figure(figsize=(16, 5.6))
    for k in range(6):
        frame = last * k // 5
        top = fig.add_subplot(2, 6, k + 1)
        image = mpimg.imread(os.path.join(directory, f'{name}_top_{k}.png'))
        top.imshow(image)  # a PNG holds RGB (cv::imwrite converts from OpenCV's BGR)
        top.set_axis_off()
        top.set_title(f't = {times[frame]:.1f} s', fontsize=9)
        draw_oblique(fig.add_subplot(2, 6, 7 + k, projection='3d'), meshes[frame], triangles, qualities[frame],
                     times[frame])
    fig.suptitle(f'The {name} policy: the reward\'s top-down camera (above) and an oblique view (below), with the '
                 f'fold quality q', fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, f'filmstrip_{name}.png'), dpi=90)
    plt.close(fig)
    # The animation: every other frame (10 per second of the rollout), shown at that rate.
    images = []
    for frame in range(0, len(meshes), 2):
        fig = plt.figure(figsize=(4.8, 3.6))
        draw_oblique(fig.add_subplot(1, 1, 1, projection='3d'), meshes[frame], triangles, qualities[frame],
                     times[frame])
        fig.tight_layout()
        fig.canvas.draw()
        images.append(Image.frombuffer('RGBA', fig.canvas.get_width_height(), fig.canvas.buffer_rgba()).convert('RGB'))
        plt.close(fig)
    images[0].save(os.path.join(directory, f'{name}.gif'), save_all=True, append_images=images[1:], duration=100,
                   loop=0)
    return True


def main():
    directory = output_directory(__doc__)
    epochs = read_epochs(os.path.join(directory, 'epochs.csv'))
    learning_curve(directory, epochs)
    coordination(directory)
    table(directory, epochs, read_rollouts(directory))
    written = [f'filmstrip_{n}.png, {n}.gif' for n in ('initial', 'final') if filmstrip(directory, n)]
    print(f'plot_fold_learning: wrote {directory}/learning_curve.png, coordination.png, table75.md, proxy.png'
          + ''.join(', ' + w for w in written))


if __name__ == '__main__':
    main()
