#!/usr/bin/env python3
"""Writes the small seed inputs under fuzz/corpus/TARGET/ that are not made
by the simulator (fuzz/run.sh adds those): hand-built .cine, .cih/.cihx +
.mraw, WAV, masks, calibration reports, pipeline and scene TOML. Each is a
few hundred bytes. Re-run after changing it: `python3 fuzz/seeds.py`."""
import json, os, struct, zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def put(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


# --- .cine (the layout of crates/io/src/cine.rs's test Builder) ---------
def cine(w, h, bit_count, compression, images, times):
    n = len(images)
    setup_len = 1600
    f = bytearray(44)
    f[0:2] = b"CI"
    f[2:4] = struct.pack("<H", 44)
    f[6:8] = struct.pack("<H", 1)
    f[20:24] = struct.pack("<I", n)
    f[24:28] = struct.pack("<I", 44)
    f[28:32] = struct.pack("<I", 84)
    bi = bytearray(40)
    bi[0:4] = struct.pack("<I", 40)
    bi[4:8] = struct.pack("<i", w)
    bi[8:12] = struct.pack("<i", h)
    bi[12:14] = struct.pack("<H", 1)
    bi[14:16] = struct.pack("<H", bit_count)
    bi[16:20] = struct.pack("<I", compression)
    bi[20:24] = struct.pack("<I", len(images[0]) if images else 0)
    f += bi
    s = bytearray(setup_len)
    s[0:2] = struct.pack("<H", 500)
    s[140:142] = b"ST"
    s[142:144] = struct.pack("<H", setup_len)
    s[768:772] = struct.pack("<I", 2200)
    s[896:900] = struct.pack("<I", 12)
    s[1568:1572] = struct.pack("<I", 123000)
    f += s
    if times is not None:
        f += struct.pack("<IHH", 8 + 8 * len(times), 1002, 0)
        for frac, sec in times:
            f += struct.pack("<II", frac, sec)
    table = len(f)
    f[32:36] = struct.pack("<I", table)
    at = table + 8 * n
    for img in images:
        f += struct.pack("<q", at)
        at += 8 + len(img)
    for img in images:
        f += struct.pack("<II", 8, len(img)) + bytes(img)
    return bytes(f)


put("cine", "u8-bottom-up", cine(3, 2, 8, 0, [[3, 4, 5, 0, 1, 2], [13, 14, 15, 10, 11, 12]],
                                [(0, 100), (1 << 31, 100)]))
put("cine", "u16-top-down", cine(2, -2, 16, 0, [struct.pack("<4H", 1, 2, 3, 4000)], None))
put("cine", "packed10", cine(4, 1, 10, 256, [bytes([0, 0x3f, 0xf8, 0x00, 0x05])], [(0, 1)]))
put("cine", "packed12l", cine(2, 1, 12, 1024, [bytes([0x34, 0xf2, 0xff])], None))
put("cine", "uninterpolated", cine(2, 2, 8, 0, [[1, 2, 3, 4]], None)[:4] + b"\x02\x00"
    + cine(2, 2, 8, 0, [[1, 2, 3, 4]], None)[6:])


# --- .cih/.cihx + .mraw: byte 0 bit 0 = cihx, bytes 1-2 = header length -
def mraw(xml, header, pixels):
    h = header.encode() if isinstance(header, str) else header
    return bytes([1 if xml else 0]) + struct.pack("<H", len(h)) + h + bytes(pixels)


def cih(w, h, frames, bits, colour="Mono"):
    return ("#Camera Information Header\nRecord Rate(fps) : 20000\nShutter Speed(s) : 1/40000\n"
            f"Total Frame : {frames}\nSave Step : 4\nImage Width : {w}\nImage Height : {h}\n"
            f"Color Type : {colour}\nColor Bit : {bits}\nFile Format : MRaw\n"
            "EffectiveBit Depth : 12\nEffectiveBit Side : Lower\n")


put("mraw", "cih-8bit", mraw(False, cih(4, 2, 2, 8), range(16)))
put("mraw", "cih-12bit", mraw(False, cih(2, 2, 1, 12), [0x12, 0x34, 0x56, 0x78, 0x9a, 0xbc]))
put("mraw", "cih-16bit-raw", mraw(False, cih(2, 1, 2, 16, "Raw"), range(8)))
cihx = (b"!!! This file can not be edited. !!!" + bytes(40)
        + b"<cih><fileInfo><fileFormat>Mraw</fileFormat></fileInfo><imageDataInfo><resolution>"
          b"<width>4</width><height>2</height></resolution><colorInfo><type>Mono</type><bit>8</bit>"
          b"</colorInfo></imageDataInfo><frameInfo><recordedFrame>400</recordedFrame><totalFrame>3"
          b"</totalFrame><skipFrame>2500</skipFrame></frameInfo><recordInfo><recordRate>50000"
          b"</recordRate><shutterSpeed>200000</shutterSpeed></recordInfo></cih>")
put("mraw", "cihx-8bit", mraw(True, cihx, [7] * 24))


# --- WAV ------------------------------------------------------------------
def wav(rate, bits, fmt, samples, channels=1):
    if fmt == 3:
        data = b"".join(struct.pack("<f", s) for s in samples)
    elif bits == 16:
        data = b"".join(struct.pack("<h", int(s * 32767)) for s in samples)
    elif bits == 24:
        data = b"".join(struct.pack("<i", int(s * 8388607))[:3] for s in samples)
    else:
        data = bytes(int(s * 127) + 128 for s in samples)
    ba = channels * bits // 8
    fmt_chunk = struct.pack("<HHIIHH", fmt, channels, rate, rate * ba, ba, bits)
    body = b"WAVE" + b"fmt " + struct.pack("<I", 16) + fmt_chunk + b"data" + struct.pack("<I", len(data)) + data
    return b"RIFF" + struct.pack("<I", len(body)) + body


tone = [((i * 37) % 64 - 32) / 40 for i in range(64)]
put("wav", "i16", wav(48000, 16, 1, tone))
put("wav", "f32", wav(2200, 32, 3, tone))
put("wav", "i24-stereo", wav(44100, 24, 1, tone, channels=2))
put("wav", "u8", wav(8000, 8, 1, tone[:16]))
put("wav", "header-claims-more", wav(48000, 16, 1, tone)[:60])


# --- masks: PGM P2/P5 (8 and 16 bit), PNG ----------------------------------
put("mask", "p5-8bit.pgm", b"P5\n4 3\n255\n" + bytes([0, 0, 255, 0, 0, 9, 9, 0, 0, 0, 0, 0]))
put("mask", "p5-16bit.pgm", b"P5\n2 2\n65535\n" + struct.pack(">4H", 0, 300, 0, 0))
put("mask", "p2.pgm", b"P2\n# comment\n3 2\n15\n0 1 0\n0 0 15\n")
put("mask", "empty.pgm", b"P5\n2 1\n255\n\x00\x00")


def png(w, h, rows, bit_depth=8):
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    raw = b"".join(b"\x00" + bytes(r) for r in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bit_depth, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


put("mask", "grey.png", png(3, 2, [[0, 255, 0], [0, 0, 1]]))


# --- calibration reports (the `effects` reusable_from_report reads) ------
put("calibration_json", "all-effects", json.dumps({"effects": [
    {"name": "time_base", "parameters": {"clock_error_ppm": 120.0}},
    {"name": "exposure", "parameters": {"exposure_us": 250.0}},
    {"name": "transfer_function", "parameters": {"frequencies_hz": [100.0, 1000.0, 4000.0],
        "coefficients_db": [0.0, -3.0, -12.0], "phase_deg": [0.0, -10.0, -45.0], "k": 1.0}},
    {"name": "dropped_frames", "parameters": {"count": 2}},
    {"name": "interference", "parameters": {"freq_hz": 50.0}},
]}, indent=1))
put("calibration_json", "no-effects", json.dumps({"effects": []}))


# --- pipeline TOML: the shipped graphs are added by run.sh; one more small one
put("pipeline_toml", "pattern-null.toml", """[pipeline]
name = "p"
[[stage]]
id = "src"
kind = "pattern"
[[stage]]
id = "sink"
kind = "null"
input = "src"
""")


# --- scene TOML (the `synthetic` source's fields at the top level) -------
put("scene_toml", "tone.toml", """width = 32
height = 24
fps = 1000.0
duration_s = 0.01
amplitude_px = 0.05
object = [8, 6, 16, 12]
signal = { type = "tone", freq_hz = 100.0 }
interference = [{ freq_hz = 50.0, amplitude_px = 0.01 }]
""")
put("scene_toml", "chirp.toml", """width = 16
height = 16
fps = 2200.0
duration_s = 0.005
bits = 12
noise_std = 0.5
signal = { type = "chirp", f0_hz = 100.0, f1_hz = 1000.0, duration_s = 0.005 }
""")


# --- wire items (crates/engine/src/wire.rs, version 1) --------------------
def vbw(kind, body):
    return b"VBW" + bytes([1, kind]) + body


def f32s(v):
    return struct.pack("<I", len(v)) + struct.pack("<%df" % len(v), *v)


put("wire", "audio", vbw(1, struct.pack("<qd", 5_000_000, 2200.0) + f32s([0.0, 0.5, -0.25])))
put("wire", "samples-times", vbw(2, struct.pack("<qdI", 7, 600.0, 2) + f32s([1, 2, 3, 4])
                                 + b"\x01" + struct.pack("<I2q", 2, 0, 1_666_667)))
put("wire", "samples", vbw(2, struct.pack("<qdI", 0, 600.0, 1) + f32s([1, 2]) + b"\x00"))
put("wire", "spectrum", vbw(3, struct.pack("<qdddIBI", 9, 0.0, 2.5, 600.0, 256, 0, 4)
                            + f32s([1e-3, 2e-3, 5e-4])))
put("wire", "peaks", vbw(4, struct.pack("<qI", 11, 2) + struct.pack("<6d", 81.0, 0.1, -20, 12, 0.01, 0.002)
                         + struct.pack("<6d", 108.0, 0.2, -25, 9, 0.02, 0.004)))
put("wire", "frame-u8", vbw(5, struct.pack("<QqIIBBdB", 3, 40, 3, 2, 8, 8, 600.0, 0) + bytes(range(6))))
put("wire", "frame-u16-rs", vbw(5, struct.pack("<QqIIBBdBdd", 4, 50, 2, 1, 16, 12, 2200.0, 1, 1e4, 2e5)
                                + struct.pack("<2H", 4000, 17)))


# --- studio HTTP requests (fuzz_targets/studio_http.rs's layout) ----------
# byte 0: bits 0-1 method (0 GET, 1 POST, 2 PUT, 3 DELETE), bit 2 token in
# the query, bit 3 in a header, bit 4 in a cookie; the target up to "\n";
# header lines up to an empty line; the body.
def req(sel, target, body=b"", headers=()):
    h = b"".join(k + b": " + v + b"\n" for k, v in headers)
    return bytes([sel]) + target.encode() + b"\n" + h + b"\n" + body


JSON = ((b"content-type", b"application/json"),)
put("studio_http", "index", req(4, "/"))
put("studio_http", "script", req(16, "/app.js"))
put("studio_http", "no-token", req(0, "/api/session"))
put("studio_http", "session", req(8, "/api/session"))
put("studio_http", "info", req(4, "/api/info?video=v.y4m"))
put("studio_http", "info-fps", req(4, "/api/info?video=v.y4m&fps=250"))
put("studio_http", "frame", req(4, "/api/frame?video=v.y4m&i=3"))
put("studio_http", "traversal", req(4, "/api/frame?video=../secret.y4m&i=0"))
put("studio_http", "symlink", req(4, "/api/info?video=sub/out.y4m"))
put("studio_http", "encoded", req(4, "/api/info%2f..%2fx?video=v.y4m"))
put("studio_http", "motion", req(5, "/api/motion", b'{"video":"v.y4m"}', JSON))
put("studio_http", "motion-roi", req(5, "/api/motion", b'{"video":"v.y4m","roi":[2,2,8,6],"fps":100}', JSON))
put("studio_http", "motion-scale", req(5, "/api/motion", b'{"video":"v.y4m","scale_mm_per_px":0.02}', JSON))
put("studio_http", "mode", req(5, "/api/mode", b'{"video":"v.y4m","freq_hz":10}', JSON))
put("studio_http", "mode-roi", req(5, "/api/mode", b'{"video":"v.y4m","freq_hz":12.5,"roi":[0,0,16,12]}', JSON))
put("studio_http", "wrong-method", req(4, "/api/motion"))
_mask = "data:image/png;base64," + __import__("base64").b64encode(
    png(16, 12, [[255 if 4 <= x < 12 and 3 <= y < 9 else 0 for x in range(16)] for y in range(12)])).decode()
put("studio_http", "motion-mask", req(5, "/api/motion", json.dumps({"video": "v.y4m", "mask": _mask}).encode(), JSON))
put("studio_http", "listen", req(5, "/api/listen", b'{"video":"v.y4m"}', JSON))
put("studio_http", "listen-roi", req(5, "/api/listen", b'{"video":"v.y4m","roi":[0,0,8,8],"fps":100}', JSON))
put("studio_http", "damping", req(5, "/api/damping", b'{"video":"v.y4m","lo_hz":5,"hi_hz":20}', JSON))
put("studio_http", "damping-roi", req(5, "/api/damping", b'{"video":"v.y4m","roi":[0,0,8,8],"lo_hz":1,"hi_hz":49.5,"fps":100}', JSON))
put("studio_http", "idv-basis", req(5, "/api/idv/basis", b'{"video":"v.y4m"}', JSON))
put("studio_http", "idv-basis-modes", req(5, "/api/idv/basis", b'{"video":"v.y4m","roi":[0,0,16,12],"modes":"10,5-20","max_modes":2,"fps":100}', JSON))
put("studio_http", "live", req(4, "/api/live"))
put("studio_http", "live-frame", req(4, "/api/live/frame"))
put("studio_http", "live-mode", req(5, "/api/live/mode", b'{"freq_hz":10}', JSON))
put("studio_http", "live-ws", req(4, "/api/live/ws", b"", ((b"upgrade", b"websocket"), (b"connection", b"Upgrade"),
                                                          (b"sec-websocket-version", b"13"),
                                                          (b"sec-websocket-key", b"dGhlIHNhbXBsZSBub25jZQ=="))))
