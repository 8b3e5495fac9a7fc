#!/usr/bin/env python3
"""Space-time slice of a side-by-side Y4M (vibroscope magnify --side-by-side):
for one column of each half, its rows over N frames from N0, original left,
magnified right, as a PGM.  Usage: space_time_slice.py IN.y4m OUT.pgm COL N0 N"""
import sys
src, out, col, n0, n = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
b = open(src, 'rb').read()
hdr, rest = b.split(b'\n', 1)
W = int([t for t in hdr.split() if t.startswith(b'W')][0][1:]); H = int([t for t in hdr.split() if t.startswith(b'H')][0][1:])
frames = []
pos = 0
while True:
    i = rest.find(b'FRAME', pos)
    if i < 0: break
    j = rest.index(b'\n', i)
    frames.append(rest[j+1:j+1+W*H]); pos = j+1+W*H
half = W // 2
# Space-time slices: rows = image rows at column `col`, columns = time; original | gap | magnified.
cols = n
img = []
for y in range(H):
    row = [frames[n0+t][y*W+col] for t in range(cols)] + [255]*4 + [frames[n0+t][y*W+half+col] for t in range(cols)]
    img.append(bytes(row))
open(out, 'wb').write(b'P5\n%d %d\n255\n' % (2*cols+4, H) + b''.join(img))
