"""
Time the chunk compressors on the records ``simulate`` writes, side by side in one run.

Run: .venv/bin/python bench/bench_compression.py [--seconds 20] [--repeat 5]

``simulate --compression none`` writes the iso230 profile on tr12x3 at 1 kHz;
the records of its chunks are then compressed as the writer compresses them
(lz4 frames of independent blocks, no content checksum; zstd at the writer's
level) and, for comparison, with lz4's faster "acceleration" levels (negative
compression levels) and larger blocks. Printed for each, the best of
``--repeat``: the CPU time scaled to 60 simulated seconds [ms] and the size
as a share of the uncompressed records. The CRC-32 the writer forms of every
chunk is timed alongside. The bare block kernel takes about 23 ms per 60 s
here (``bench/bench_simulate.py``), so a compressor over 35 ms per 60 s
cannot fit the 1.5x budget even alone on the second core.
"""
import argparse
import os
import sys
import tempfile
import time
import zlib

import lz4.frame
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
import zstandard

from leadscrew_sim import cli

#: The writer's zstd level (McapWriter's default).
ZSTD_LEVEL = 1


def chunk_records(seconds):
    """Return the uncompressed records of every chunk of a ``seconds`` [s] simulate run."""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, 'none.mcap')
        out, sys.stdout = sys.stdout, open(os.devnull, 'w')
        try:
            rc = cli.main(['simulate', '--excite', 'iso230', '--duration', str(seconds),
                           '--compression', 'none', '-q', '-o', path])
        finally:
            sys.stdout.close()
            sys.stdout = out
        if rc != 0:
            sys.exit(rc)
        with open(path, 'rb') as fh:
            return [r.data for r in StreamReader(fh, emit_chunks=True).records
                    if isinstance(r, Chunk)]


def best_of(repeat, fn, pieces):
    """Return (best wall time [s], total output bytes) of ``fn`` over every piece."""
    best, size = float('inf'), 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = [fn(p) for p in pieces]
        best = min(best, time.perf_counter() - t0)
        size = sum(len(o) for o in out)
    return best, size


def main():
    """Print the compressors' time per 60 simulated seconds and their size ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated time [s]')
    ap.add_argument('--repeat', type=int, default=5, help='runs of each; the best counts')
    a = ap.parse_args()
    pieces = chunk_records(a.seconds)
    n = sum(len(p) for p in pieces)
    scale = 60.0 / a.seconds * 1e3
    zstd = zstandard.ZstdCompressor(level=ZSTD_LEVEL)

    def lz4_at(level, block_size=lz4.frame.BLOCKSIZE_DEFAULT):
        return lambda p: lz4.frame.compress(p, compression_level=level, block_size=block_size,
                                            block_linked=False, content_checksum=False)

    runs = [('crc32', lambda p: zlib.crc32(p).to_bytes(4, 'little'))]
    runs += [(f'lz4 level {lv}' + (' (written)' if lv == 0 else ''), lz4_at(lv))
             for lv in (0, -1, -4, -8, -16)]
    runs += [('lz4 level 0, 4 MiB blocks', lz4_at(0, lz4.frame.BLOCKSIZE_MAX4MB)),
             (f'zstd level {ZSTD_LEVEL} (written)', zstd.compress)]
    print(f'{len(pieces)} chunks, {n / 1e6:.1f} MB of records ({a.seconds:g} s simulated), '
          f'best of {a.repeat}')
    print(f'{"":<28} {"ms per 60 s":>12} {"size / records":>15}')
    for name, fn in runs:
        wall, size = best_of(a.repeat, fn, pieces)
        ratio = f'{size / n:15.3f}' if name != 'crc32' else ''
        print(f'{name:<28} {wall * scale:12.1f} {ratio}')


if __name__ == '__main__':
    main()
