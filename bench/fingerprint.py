"""
Fingerprint the package's numerical behaviour, to compare two versions of the code bit for bit.

Run: .venv/bin/python bench/fingerprint.py [--seconds 10] [--out DIR]

For every preset and four drives (hold: zero torque; track: a PD loop on the
motor angle tracking x = 50 mm sin(2 pi 0.5 Hz t); sine: 0.5 max_torque at
1 Hz; move: simulate's position move) it prints one SHA-256 per line (a
stepper preset takes no torque: hold, track and sine are its position hold,
position and velocity commands along x = 20 mm sin(2 pi 0.5 Hz t), move
simulate's trapezoid):
- ``model``: every output array of ``model.run`` in 1 s blocks, and every
  ``StepOutput`` of a tick-by-tick run (hold, track, sine);
- ``simulate``: every message of the MCAP that ``leadscrew_sim simulate``
  writes (topic, log time, publish time, sequence, payload bytes);
- ``resim``: the same for the MCAP that ``leadscrew_sim resim`` writes of it.
Two versions of the code agree when the printed lines are identical
(``diff`` the outputs). Wall-clock metadata is not part of any hash.
"""
import argparse
import hashlib
import math
from pathlib import Path
import tempfile

from mcap.stream_reader import StreamReader
from mcap.records import Channel, Message
import numpy as np

from leadscrew_sim import LeadScrewModel, load_preset, preset_names
from leadscrew_sim.cli import main as cli_main


def track_torques(params, n, dt=1e-3, amplitude=0.05, freq=0.5, bandwidth=20.0):
    """Motor torques [N m] of a PD loop on the motor angle, run tick by tick."""
    m = LeadScrewModel(params, dt=dt)
    rt = params.lead / (2 * math.pi)
    j = params.motor_inertia + params.screw_inertia + \
        (params.nut_mass + params.payload_mass) * rt ** 2
    w = 2 * math.pi * bandwidth
    kp, kd = j * w * w, 2 * 0.7 * w * j
    hs = params.hand_sign
    out = np.empty(n)
    for i in range(n):
        o = m.output()
        q_ref = amplitude * math.sin(2 * math.pi * freq * (i * dt)) / rt
        t_q = kp * (q_ref - hs * o.motor_angle) - kd * hs * o.motor_velocity
        t_q = min(max(t_q, -params.max_torque), params.max_torque)
        out[i] = hs * t_q
        m.advance(out[i])
    return out


def model_hash(params, torques, keys=None):
    """SHA-256 of model.run in 1 s blocks and of a tick-by-tick run (``keys``: these only)."""
    h = hashlib.sha256()
    m = LeadScrewModel(params, dt=1e-3)
    for i in range(0, len(torques), 1000):
        res = m.run(torques[i:i + 1000])
        for key in sorted(res if keys is None else keys):
            h.update(key.encode())
            h.update(np.ascontiguousarray(res[key]).tobytes())
    m = LeadScrewModel(params, dt=1e-3)
    for tq in torques:
        o = m.step(float(tq))
        h.update(repr(o).encode())
    h.update(repr(sorted(m.energy().items())).encode())
    return h.hexdigest()


def stepper_model_hash(params, rows, keys=None):
    """SHA-256 of a stepper's model.run on command rows in 1 s blocks and tick by tick."""
    h = hashlib.sha256()
    m = LeadScrewModel(params, dt=1e-3)
    for i in range(0, len(rows), 1000):
        res = m.run(None, commands=rows[i:i + 1000])
        for key in sorted(res if keys is None else keys):
            h.update(key.encode())
            h.update(np.ascontiguousarray(res[key]).tobytes())
    m = LeadScrewModel(params, dt=1e-3)
    for row in rows:
        m.command(*row)
        m.advance_held()
        h.update(repr(m.output()).encode())
    h.update(repr(sorted(m.energy().items())).encode())
    return h.hexdigest()


def stepper_prints(name, p, n, out, seconds, skip):
    """Print the lines of a stepper preset: position hold and sine, velocity sine; simulate."""
    t = np.arange(n) * 1e-3
    m = LeadScrewModel(p)
    x = p.initial_position + 0.02 * np.sin(2 * math.pi * 0.5 * t)
    rows = dict(hold=np.tile([2.0, m.output().motor_angle, math.nan, math.nan], (n, 1)),
                track=np.column_stack([np.full(n, 2.0), m.nut_to_motor(x), np.full(n, math.nan),
                                       np.full(n, math.nan)]),
                sine=np.column_stack([np.full(n, 1.0), np.full(n, math.nan),
                                      m.nut_to_motor(x) - m.output().motor_angle,
                                      np.full(n, math.nan)]))
    for drive, r in rows.items():
        print(f'{name:<14} {drive:<6} model    {stepper_model_hash(p, r)}', flush=True)
    csv = out / f'{name}_track.csv'
    csv.write_text(''.join(f'{k * 1e-3!r},{float(v)!r}\n' for k, v in enumerate(x)))
    sim_args = dict(hold=[], track=['--position-csv', str(csv)],
                    move=['--profile', 'trapezoid'])
    for drive, extra in sim_args.items():
        f = out / f'{name}_{drive}.mcap'
        rc = cli_main(['simulate', '--preset', name, '--duration', str(seconds),
                       '-q', '-o', str(f)] + extra)
        print(f'{name:<14} {drive:<6} simulate rc={rc} {mcap_hash(f, skip)}', flush=True)
        r = out / f'{name}_{drive}.resim.mcap'
        rc = cli_main(['resim', str(f), '-q', '-o', str(r)])
        print(f'{name:<14} {drive:<6} resim    rc={rc} {mcap_hash(r, skip)}', flush=True)


def mcap_hash(path, skip=()):
    """SHA-256 of every message of an MCAP file (topic, times, sequence, payload) not in skip."""
    h = hashlib.sha256()
    topics = {}
    count = 0
    with open(path, 'rb') as f:
        for rec in StreamReader(f, skip_magic=False).records:
            if isinstance(rec, Channel):
                topics[rec.id] = rec.topic
            elif isinstance(rec, Message) and topics[rec.channel_id] not in skip:
                h.update(topics[rec.channel_id].encode())
                h.update(rec.log_time.to_bytes(8, 'little'))
                h.update(rec.publish_time.to_bytes(8, 'little'))
                h.update(rec.sequence.to_bytes(4, 'little'))
                h.update(rec.data)
                count += 1
    return f'{h.hexdigest()} ({count} messages)'


def main():
    """Print the fingerprints."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=10.0)
    ap.add_argument('--out', help='keep the MCAP files here (default: a temporary directory)')
    ap.add_argument('--model-keys', help='hash only these comma-separated columns of '
                    'model.run (to compare with a version that has fewer)')
    ap.add_argument('--skip-topics', default='', help='comma-separated topics left out of '
                    'the MCAP hashes (to compare with a version without them)')
    args = ap.parse_args()
    keys = args.model_keys.split(',') if args.model_keys else None
    skip = set(filter(None, args.skip_topics.split(',')))
    n = int(round(args.seconds / 1e-3))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out or tmp)
        out.mkdir(parents=True, exist_ok=True)
        for name in preset_names():
            p = load_preset(name)
            if p.drive_type == 'stepper':
                stepper_prints(name, p, n, out, args.seconds, skip)
                continue
            t = np.arange(n) * 1e-3
            track = track_torques(p, n)
            drives = dict(hold=np.zeros(n), track=track,
                          sine=0.5 * p.max_torque * np.sin(2 * math.pi * t))
            for drive, tq in drives.items():
                print(f'{name:<14} {drive:<6} model    {model_hash(p, tq, keys)}', flush=True)
            csv = out / f'{name}_track.csv'
            csv.write_text(''.join(f'{k * 1e-3!r},{float(v)!r}\n' for k, v in enumerate(track)))
            sim_args = dict(hold=['--torque', '0'], track=['--torque-csv', str(csv)],
                            sine=['--profile', 'sine'], move=['--profile', 'move'])
            for drive, extra in sim_args.items():
                f = out / f'{name}_{drive}.mcap'
                rc = cli_main(['simulate', '--preset', name, '--duration', str(args.seconds),
                               '-q', '-o', str(f)] + extra)
                print(f'{name:<14} {drive:<6} simulate rc={rc} {mcap_hash(f, skip)}', flush=True)
                r = out / f'{name}_{drive}.resim.mcap'
                rc = cli_main(['resim', str(f), '-q', '-o', str(r)])
                print(f'{name:<14} {drive:<6} resim    rc={rc} {mcap_hash(r, skip)}', flush=True)


if __name__ == '__main__':
    main()
