#!/usr/bin/env python3
"""Plots of a fold_learner run: reads DIR/epochs.csv, DIR/rollouts.csv, DIR/coordination.csv and DIR/summary.json,
writes DIR/learning_curve.png (per algorithm and epoch: the fold quality q of the noise-free policy, the headline,
and of the exploring rollouts, their reward and its terms; bands: 95 % Student-t intervals over the runs),
DIR/coordination.png (the final coordination matrices, thesis Fig. 7.9d), DIR/proxy.png and DIR/table75.md (the
learned policies, the rollouts to q >= 0.8, tests with Holm's correction, the reward against q run by run, the
measured Table 7.5 next to the thesis'); and, from
DIR/NAME_frames.csv, NAME_triangles.csv and NAME_top_K.png that fold_learner writes for the initial and the final
policy, DIR/filmstrip_NAME.png (six moments: the top-down camera above, an oblique view below, q under each) and
DIR/NAME.gif (the oblique view of the whole rollout); from DIR/final_runs/, DIR/final_runs.png (every run's final
policy as the camera saw it, with its q).

With --beside LABEL=OTHER (repeatable), table75.md also compares the final policies of OTHER runs (each a
fold_learner run of one algorithm with one setting changed, e.g. LABEL "weights only" for _policy:=weights) with the
same algorithm in DIR: an ablation table, one claim per column, Holm-corrected over the ablations.

Usage: plot_fold_learning.py DIR [--beside LABEL=OTHER ...]
"""
import csv
import json
import math
import os
import re
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
from plot_common import bootstrap_mean_ci, holm, mean_ci  # noqa: E402
from scipy import stats  # noqa: E402

# Thesis Table 7.5: mean reward of the rollouts at epoch 1 and epoch 15 (3 runs).
THESIS_75 = {'DR-DMP0(12)': (-2.47, -1.14), 'IDR-DMP_CMU': (-2.48, -0.91), 'IDR-DMP_MCMU(3)': (-2.57, -1.00)}
# The fold quality a policy should reach (issue target), and the reward signals compared with q.
Q_TARGET = 0.8
# Each as a function of a rollouts.csv row and the acceleration cost A = int |qdd|^2 dt (the run's R_acceleration
# over its w_a), whatever reward the run learned on: the two named reward settings and their terms.
PROXY_SIGNALS = [
    ('fold reward (default)', lambda r, a: -0.001 * a - float(r['fold_mismatch'])),
    ('thesis reward (7.52)', lambda r, a: -0.01 * a - (1.0 - float(r['fill_ratio'])) - float(r['mean_gradient'])),
    ('goal reward', lambda r, a: -0.002 * a - float(r['goal_mismatch'])),
    ('-R_acceleration', lambda r, a: -a),
    ('-fold mismatch E/E_flat', lambda r, a: -float(r['fold_mismatch'])),
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
    fig, axes = plt.subplots(1, 4, figsize=(22, 4.5))
    runs = max(len(rows) for per_epoch in epochs.values() for rows in per_epoch.values())
    band_name = f'95 % t-interval over {runs} runs' if runs > 1 else 'the rollouts\' std'
    for algorithm, per_epoch in epochs.items():
        xs = sorted(per_epoch)
        policy = [mean_ci([float(r['policy_fold_quality']) for r in per_epoch[e]]) for e in xs]
        line, = axes[0].plot(xs, [m for m, _ in policy], marker='o', label=algorithm)
        color = line.get_color()
        axes[0].fill_between(xs, [m - d for m, d in policy], [m + d for m, d in policy], color=color, alpha=0.2)
        q = [band(per_epoch[e], 'fold_quality', 'fold_quality_std') for e in xs]
        axes[1].plot(xs, [m for m, _ in q], marker='o', color=color, label=algorithm)
        axes[1].fill_between(xs, [m - d for m, d in q], [m + d for m, d in q], color=color, alpha=0.2)
        reward = [band(per_epoch[e], 'mean_reward', 'std_reward') for e in xs]
        axes[2].plot(xs, [m for m, _ in reward], marker='o', color=color, label=algorithm)
        axes[2].fill_between(xs, [m - d for m, d in reward], [m + d for m, d in reward], color=color, alpha=0.2)
        for term, style in (('r_acceleration', ':'), ('r_color', '--'), ('r_depth', '-.'), ('r_goal', '-'),
                            ('r_fold', '-')):
            values = [sum(float(r[term]) for r in per_epoch[e]) / len(per_epoch[e]) for e in xs]
            if any(values) and max(values) < 10.0:  # terms the setting weighs by 0, and failed rollouts' blow-ups
                axes[3].plot(xs, values, style, color=color, label=f'{algorithm} {term}')
    for ax in axes[:2]:
        ax.axhline(Q_TARGET, color='grey', lw=0.8, ls='--')
        ax.set_ylabel('fold quality q (1: ideal fold, 0: flat)')
    axes[0].set_title(f'The noise-free policy\'s fold quality q\n(band: {band_name})', fontsize=10)
    axes[1].set_title(f'The exploring rollouts\' mean q, failures included\n(band: {band_name})', fontsize=10)
    axes[2].set_ylabel(f'reward ({reward_setting(directory)} setting)')
    axes[2].set_title(f'Mean reward of the rollouts\n(band: {band_name})', fontsize=10)
    axes[3].set_ylabel('penalty')
    axes[3].set_title('Reward terms (mean over the rollouts)', fontsize=10)
    for ax in axes:
        ax.set_xlabel('epoch (policy updates)')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'learning_curve.png'), dpi=90)
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


def runs_of(per_epoch):
    return sorted({int(r['run']) for rows in per_epoch.values() for r in rows})


def policy_quality(per_epoch, run, epoch):
    for r in per_epoch[epoch]:
        if int(r['run']) == run:
            return float(r['policy_fold_quality'])
    return math.nan


def rollouts_to_target(per_epoch, rollouts_per_epoch, target=Q_TARGET):
    """Per run, the exploring rollouts drawn before the first noise-free policy with q >= target (the policy of epoch
    e follows e updates of `rollouts_per_epoch`); math.inf for a run that never reaches it."""
    needed = []
    for run in runs_of(per_epoch):
        reached = [e for e in sorted(per_epoch) if policy_quality(per_epoch, run, e) >= target]
        needed.append(reached[0] * rollouts_per_epoch if reached else math.inf)
    return needed


def per_run_spearman(rollouts, signal, weight):
    """Spearman's rho of `signal` with q over each run's exploring rollouts (failures included): one value per run."""
    values = []
    for key in sorted({(r['algorithm'], r['run']) for r in rollouts}):
        rows = [r for r in rollouts if (r['algorithm'], r['run']) == key]
        x = [signal(r, float(r['r_acceleration']) / weight) for r in rows]
        q = [float(r['fold_quality']) for r in rows]
        if len(rows) > 2 and len(set(x)) > 1 and len(set(q)) > 1:
            values.append(stats.spearmanr(x, q)[0])
    return values


def fmt_rollouts(n):
    return 'never' if math.isinf(n) else f'{n:.0f}'


def learned_policies(epochs, rollouts_per_epoch, reference=None):
    """Markdown lines: the noise-free policies before and after, the rollouts to q >= Q_TARGET, and the tests of the
    reference algorithm (IDR-DMP_CMU when there) against each other one, Holm-corrected per claim."""
    last = {a: max(per_epoch) for a, per_epoch in epochs.items()}
    lines = [f'The noise-free policy, what the learning gives a user: its fold quality q before the first and after '
             f'the last update (mean ± 95 % Student-t interval over the runs), the runs whose final policy reaches q '
             f'≥ {Q_TARGET}, and the exploring rollouts drawn before the policy first reached it (median over the '
             'runs, a run that never did counted as never):', '',
             '| algorithm | runs | initial q | final q | final reward | final q ≥ 0.8 | rollouts to q ≥ 0.8, median '
             '(range) |', '|---|---:|---:|---:|---:|---:|---|']
    needed = {}
    for algorithm, per_epoch in epochs.items():
        first = [float(r['policy_fold_quality']) for r in per_epoch[0]]
        final = [float(r['policy_fold_quality']) for r in per_epoch[last[algorithm]]]
        reward = [float(r['policy_reward']) for r in per_epoch[last[algorithm]]]
        needed[algorithm] = rollouts_to_target(per_epoch, rollouts_per_epoch)
        reached = sorted(n for n in needed[algorithm] if not math.isinf(n))
        span = f' ({reached[0]:.0f}–{reached[-1]:.0f})' if reached else ''
        lines.append(f'| {algorithm} | {len(final)} | {interval(first)} | **{interval(final)}** | {interval(reward)} | '
                     f'{sum(q >= Q_TARGET for q in final)}/{len(final)} | '
                     f'{fmt_rollouts(np.median(needed[algorithm]))}{span} |')
    lines.append('')
    names = list(epochs)
    reference = reference if reference in epochs else ('IDR-DMP_CMU' if 'IDR-DMP_CMU' in epochs else names[0])
    others = [a for a in names if a != reference]
    if not others or min(len(v) for v in needed.values()) < 2:
        return lines
    tests = []
    for other in others:
        u = stats.mannwhitneyu(needed[reference], needed[other], alternative='less')
        v = stats.mannwhitneyu(needed[reference], needed[other], alternative='greater')
        x = [float(r['policy_fold_quality']) for r in epochs[reference][last[reference]]]
        y = [float(r['policy_fold_quality']) for r in epochs[other][last[other]]]
        welch = stats.ttest_ind(x, y, equal_var=False)
        tests.append((other, u.pvalue, v.pvalue, np.mean(x) - np.mean(y), welch.pvalue))
    fewer = holm([t[1] for t in tests])
    more = holm([t[2] for t in tests])
    better = holm([t[4] for t in tests])
    lines += [f'{reference} against each other algorithm, three claims, each tested against the {len(others)} others '
              'with Holm\'s correction: it reaches q ≥ 0.8 in fewer rollouts (the thesis\' claim) or the other does '
              '(Mann–Whitney U, one-sided each; "never" ranks last), and its final policy folds differently (Welch\'s '
              't, two-sided):', '',
              f'| against | {reference} fewer rollouts: p | Holm | the other fewer: p | Holm | final q difference | p '
              '| Holm |', '|---|---:|---:|---:|---:|---:|---:|---:|']
    for (other, p_u, p_v, diff, p_w), h_u, h_v, h_w in zip(tests, fewer, more, better):
        lines.append(f'| {other} | {p_u:.3g} | {h_u:.3g} | {p_v:.3g} | {h_v:.3g} | {diff:+.3f} | {p_w:.3g} | '
                     f'{h_w:.3g} |')
    lines.append('')
    return lines


def ablations(epochs, rollouts_per_epoch, beside):
    """Markdown lines: each ablation run's (LABEL, epochs of one algorithm) final noise-free policy against the same
    algorithm in `epochs`, with Welch's t on the final q and Mann-Whitney U on the rollouts to q >= Q_TARGET (both
    two-sided), each claim Holm-corrected over the ablations."""
    rows, tests = [], []
    for label, other in beside:
        if len(other) != 1:
            sys.exit(f'plot_fold_learning: the ablation {label!r} has {len(other)} algorithms; one is compared')
        algorithm, per_epoch = next(iter(other.items()))
        if algorithm not in epochs:
            sys.exit(f'plot_fold_learning: the ablation {label!r} learned with {algorithm}, which the run does not have')
        reference = epochs[algorithm]
        final = [float(r['policy_fold_quality']) for r in per_epoch[max(per_epoch)]]
        base = [float(r['policy_fold_quality']) for r in reference[max(reference)]]
        needed = rollouts_to_target(per_epoch, rollouts_per_epoch)
        base_needed = rollouts_to_target(reference, rollouts_per_epoch)
        dims = np.mean([float(r['latent_dims']) for r in per_epoch[max(per_epoch)]])
        rows.append((f'{algorithm}, {label}', final, needed, dims))
        tests.append((np.mean(final) - np.mean(base), stats.ttest_ind(final, base, equal_var=False).pvalue,
                      stats.mannwhitneyu(needed, base_needed, alternative='two-sided').pvalue))
    if not rows:
        return []
    welch = holm([t[1] for t in tests])
    mann = holm([t[2] for t in tests])
    lines = ['Ablations: one setting changed, the same algorithm, runs and budget; their final noise-free policy and the '
             'rollouts to q ≥ 0.8 against the same algorithm above (Welch\'s t on the final q, Mann–Whitney U on the '
             f'rollouts, both two-sided, each Holm-corrected over the {len(rows)} ablations):', '',
             '| setting | runs | final q | final q ≥ 0.8 | rollouts to q ≥ 0.8, median | final r | q difference | p | '
             'Holm | rollouts: p | Holm |', '|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|']
    for (name, final, needed, dims), (diff, p_w, p_u), h_w, h_u in zip(rows, tests, welch, mann):
        lines.append(f'| {name} | {len(final)} | {interval(final)} | {sum(q >= Q_TARGET for q in final)}/{len(final)} '
                     f'| {fmt_rollouts(np.median(needed))} | {dims:.1f} | {diff:+.3f} | {p_w:.3g} | {h_w:.3g} | '
                     f'{p_u:.3g} | {h_u:.3g} |')
    lines.append('')
    return lines


def table(directory, epochs, rollouts, beside=()):
    """table75.md: the learned noise-free policies and the tests behind the claims (learned_policies()); the
    exploring rollouts' mean reward and q at a few epochs (mean ± 95 % t-interval over the runs, failures counted);
    how the camera reward and its terms follow q within each run (Spearman, bootstrap over the runs)."""
    summary = json.load(open(os.path.join(directory, 'summary.json')))
    rollouts_per_epoch = max(int(r['index']) for r in rollouts if r['kind'] == 'sample') + 1
    lines = learned_policies(epochs, rollouts_per_epoch) + ablations(epochs, rollouts_per_epoch, beside)
    last = min(max(per_epoch) for per_epoch in epochs.values())
    shown = sorted({0, min(5, last), min(10, last), last})
    for column, title in (('mean_reward', f'Mean reward ({reward_setting(directory)} setting) of the exploring '
                                          'rollouts'),
                          ('fold_quality', 'Fold quality q of the exploring rollouts (cloth mesh)')):
        lines += [f'{title}: mean ± 95 % Student-t interval over the runs (one value per run: the mean of its '
                  'rollouts at that epoch, failed ones included)', '',
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
    samples = [r for r in rollouts if r['kind'] == 'sample']
    weight = acceleration_weight(directory)
    per_run = [(label, per_run_spearman(samples, signal, weight)) for label, signal in PROXY_SIGNALS]
    if per_run and per_run[0][1]:
        runs = len(per_run[0][1])
        lines += [f'Does the reward follow the fold? Spearman\'s rho of each signal with q over the exploring rollouts '
                  f'of each run (failures included), the mean over the {runs} runs and its bootstrap 95 % interval '
                  '(resampling runs); penalties negated, so a good proxy has rho near 1:', '',
                  '| signal | mean rho over the runs | 95 % interval |', '|---|---:|---|']
        for label, values in per_run:
            if values:
                m, lo, hi = bootstrap_mean_ci(values)
                lines.append(f'| {label} | {m:.3f} | [{lo:.3f}, {hi:.3f}] |')
        lines.append('')
        proxy_scatter(directory, [r for r in samples if r['outcome'] == 'Ok'], weight)
    for r in summary['results']:
        if r.get('experiment') == 'repetitions':
            lines.append(f"Initial policy over {r['repetitions']} noise-free repetitions: R = {r['mean_reward']:.3f} ± "
                         f"{r['std_reward']:.3f}, rho = {r['fill_ratio']:.3f} ± {r['fill_ratio_std']:.3f}, "
                         f"gbar = {r['mean_gradient']:.3f} ± {r['mean_gradient_std']:.3f} (thesis: R_color 0.799 ± "
                         f"0.088, R_depth 0.473 ± 0.029; std over the repetitions)")
    with open(os.path.join(directory, 'table75.md'), 'w') as f:
        f.write('\n'.join(lines) + '\n')


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


def draw_oblique(ax, mesh, triangles, q, t, centre):
    """The cloth seen from the front left and above, its triangles shaded by height; `centre` the flat cloth's."""
    polygons = mesh[triangles]
    heights = polygons[:, :, 2].mean(axis=1)
    collection = Poly3DCollection(polygons, facecolors=plt.cm.viridis(np.clip((heights - 0.15) / 0.25, 0, 1)),
                                  edgecolors='none')
    ax.add_collection3d(collection)
    ax.set_xlim(centre[0] - 0.3, centre[0] + 0.3)
    ax.set_ylim(centre[1] - 0.35, centre[1] + 0.35)
    ax.set_zlim(0.1, 0.5)
    ax.view_init(elev=30, azim=-120)
    ax.set_axis_off()
    ax.set_title(f't = {t:.1f} s, q = {q:.2f}', fontsize=9)


def camera_filmstrip(directory, name):
    """A robot run without the cloth's ground truth: the camera's six images only."""
    fig, axes = plt.subplots(1, 6, figsize=(16, 2.9))
    for k, ax in enumerate(axes):
        ax.imshow(mpimg.imread(os.path.join(directory, f'{name}_top_{k}.png')))
        ax.set_axis_off()
    fig.suptitle(f'The {name} policy: the camera\'s images over the rollout', fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, f'filmstrip_{name}.png'), dpi=90)
    plt.close(fig)
    return f'filmstrip_{name}.png'


def filmstrip(directory, name):
    """filmstrip_NAME.png and NAME.gif from the rollout's frames; what it wrote ('' for nothing)."""
    frames = read_frames(directory, name)
    if frames is None:
        if os.path.exists(os.path.join(directory, f'{name}_top_0.png')):
            return camera_filmstrip(directory, name)
        return ''
    times, qualities, meshes, triangles = frames
    centre = meshes[0][:, :2].mean(axis=0)
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
                     times[frame], centre)
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
                     times[frame], centre)
        fig.tight_layout()
        fig.canvas.draw()
        images.append(Image.frombuffer('RGBA', fig.canvas.get_width_height(), fig.canvas.buffer_rgba()).convert('RGB'))
        plt.close(fig)
    images[0].save(os.path.join(directory, f'{name}.gif'), save_all=True, append_images=images[1:], duration=100,
                   loop=0)
    return f'filmstrip_{name}.png, {name}.gif'


def arguments():
    """DIR and the --beside LABEL=OTHER pairs of the command line (usage: the module's doc)."""
    args = sys.argv[1:]
    if args in (['-h'], ['--help']):
        print(__doc__)
        sys.exit(0)
    if not args or args[0].startswith('-') or len(args) % 2 == 0:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    beside = []
    for flag, value in zip(args[1::2], args[2::2]):
        label, _, other = value.rpartition('=')
        if flag != '--beside' or not label or not other:
            print(f'plot_fold_learning: expected --beside LABEL=OTHER, got {flag} {value}\n{__doc__}', file=sys.stderr)
            sys.exit(2)
        beside.append((label, read_epochs(os.path.join(other, 'epochs.csv'))))
    return args[0], beside


def runs_sheet(directory, epochs):
    """DIR/final_runs.png from the camera's final image of every run's final policy (DIR/final_runs/, written by
    fold_learner's simulation backend): a row per algorithm, a column per run, each titled with its q."""
    folder = os.path.join(directory, 'final_runs')
    if not os.path.isdir(folder):
        return ''
    rows = [(a, per_epoch) for a, per_epoch in epochs.items()]
    columns = max(len(runs_of(per_epoch)) for _, per_epoch in rows)
    fig, axes = plt.subplots(len(rows), columns, figsize=(1.6 * columns, 1.5 * len(rows) + 0.5), squeeze=False)
    for i, (algorithm, per_epoch) in enumerate(rows):
        name = re.sub(r'[^A-Za-z0-9_-]', '_', algorithm)
        runs = runs_of(per_epoch)
        for j in range(columns):
            ax = axes[i][j]
            ax.axis('off')
            if j >= len(runs):
                continue
            path = os.path.join(folder, f'{name}_run_{runs[j]}.png')
            if not os.path.exists(path):
                continue
            ax.imshow(mpimg.imread(path))
            q = policy_quality(per_epoch, runs[j], max(per_epoch))
            ax.set_title(f'{algorithm}\nrun {runs[j]}: q {q:.2f}' if j == 0 else f'run {runs[j]}: q {q:.2f}',
                         fontsize=7, color='C3' if q < Q_TARGET else 'black')
    fig.suptitle('The final noise-free policy of every run: the camera\'s last image, q (red: below 0.8)', fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'final_runs.png'), dpi=90)
    plt.close(fig)
    return ', final_runs.png'


def main():
    directory, beside = arguments()
    epochs = read_epochs(os.path.join(directory, 'epochs.csv'))
    learning_curve(directory, epochs)
    coordination(directory)
    table(directory, epochs, read_rollouts(directory), beside)
    written = [w for w in (filmstrip(directory, n) for n in ('initial', 'final')) if w]
    print(f'plot_fold_learning: wrote {directory}/learning_curve.png, coordination.png, table75.md, proxy.png'
          + ''.join(', ' + w for w in written) + runs_sheet(directory, epochs))


if __name__ == '__main__':
    main()
