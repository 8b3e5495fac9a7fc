#!/usr/bin/env python3
"""Space-time slice of a side-by-side Y4M (vibroscope magnify --side-by-side):
for one column of each half, its rows over N frames from N0, original left,
magnified right, as a PGM.  Usage: space_time_slice.py IN.y4m OUT.pgm COL N0 N"""
import sys
src, out, col, n0, n = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
b = open(src, 'rb').read()
hdr, rest = b.split(b'\n', 1)
W = int([t for t in hdr.split() if t.startswith(b'W')][0][1:]); H = int([t for t in hdr.split() if t.startswith(b'H')][0][1:])
C = ([t[1:] for t in hdr.split() if t.startswith(b'C')] or [b'420jpeg'])[0]
# Bytes of one frame: the luma, then the chroma planes (colour output is 4:4:4).
size = {b'mono': W*H, b'444': 3*W*H}.get(C, W*H + 2*((W+1)//2)*((H+1)//2))
frames = []
pos = 0
while pos < len(rest):
    j = rest.index(b'\n', pos)
    assert rest[pos:j].startswith(b'FRAME'), 'not a frame header at byte %d' % pos
    frames.append(rest[j+1:j+1+W*H]); pos = j+1+size
half = W // 2
# Space-time slices: rows = image rows at column `col`, columns = time; original | gap | magnified.
cols = n
img = []
for y in range(H):
    row = [frames[n0+t][y*W+col] for t in range(cols)] + [255]*4 + [frames[n0+t][y*W+half+col] for t in range(cols)]
    img.append(bytes(row))
open(out, 'wb').write(b'P5\n%d %d\n255\n' % (2*cols+4, H) + b''.join(img))
