#!/usr/bin/python3
"""sirad hostile-peer tests (issue: hardening): real sirad-coordinator and sirad-node processes
over loopback TCP, and a SIRAD/1 peer written here in Python (pyzmq, and the project's
proto/sirad.proto compiled by protoc --python_out) that lies, floods or stalls. Each case asserts
that the run still ends correctly and that the attacked process's peak memory (ru_maxrss from
wait4, the kernel's VmHWM of the child) stays under a stated bound.

    hostile.py --build BUILD_DIR --case NAME   (one ctest per case: tests/CMakeLists.txt)
    hostile.py --build BUILD_DIR --list

Every wait is for an event (a file appears, a log line, a message, a process exit), with a
generous cap that only turns a hang into a failure; no case depends on how fast anything runs.

The farm section (cases farm_*) attacks a farm (sirad-coordinator --serve) from its HTTP side
and from its nodes: hostile requests, a job whose bundles crash every node. Slow clients,
hostile job specs and a hostile farm's answers to `sirad jobs` are tests/cmd/processes_test.cpp's
Farm.* and tests/cmd/farm_client_test.cpp.
"""
import argparse
import math
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time

import zmq

SIG = b"SIRAD1"
CMD = {"hello": 0x01, "welcome": 0x02, "scene": 0x03, "ready": 0x04, "grant": 0x05, "report": 0x06,
       "update": 0x07, "stop": 0x08, "final": 0x09, "heartbeat": 0x0A, "bye": 0x0B, "image": 0x0C, "tiles": 0x0D,
       "pixels": 0x0E, "error": 0x0F}
NAME = {v: k for k, v in CMD.items()}
CAP_S = 240  # the cap on any one wait: a hang fails the case instead of blocking ctest

pb = None  # sirad_pb2, imported in main() from the build tree


class Failure(Exception):
    pass


def check(cond, what):
    if not cond:
        raise Failure(what)


# --- processes ------------------------------------------------------------------------------

class Proc:
    """A child process with its output in a log file; wait() reaps it with wait4 and keeps its
    exit code and peak resident memory (ru_maxrss, KiB). Every child still running when the case
    ends, passed or failed, is killed (Proc.kill_all)."""

    running = []

    @classmethod
    def kill_all(cls):
        for p in cls.running:
            if p.poll() is None:
                p.p.kill()
                p.wait(30)

    def __init__(self, args, log_path, env=None):
        self.args = args
        self.log_path = log_path
        self.log_file = open(log_path, "wb")
        self.p = subprocess.Popen(args, stdout=self.log_file, stderr=subprocess.STDOUT, env=env)
        self.rc = None
        self.maxrss_kib = None
        Proc.running.append(self)

    def poll(self):
        if self.rc is None:
            pid, status, ru = os.wait4(self.p.pid, os.WNOHANG)
            if pid:
                self.rc = os.waitstatus_to_exitcode(status)
                self.maxrss_kib = ru.ru_maxrss
                self.p.returncode = self.rc
                self.log_file.close()
        return self.rc

    def wait(self, cap_s=CAP_S):
        end = time.monotonic() + cap_s
        while self.poll() is None:
            if time.monotonic() > end:
                self.p.kill()
                raise Failure(f"{os.path.basename(self.args[0])} did not exit within {cap_s} s")
            time.sleep(0.02)
        return self.rc

    def stop(self):
        if self.poll() is None:
            self.p.send_signal(signal.SIGTERM)
            try:
                self.wait(30)
            except Failure:
                pass

    def log(self):
        with open(self.log_path, "rb") as f:
            return f.read().decode(errors="replace")


def wait_until(what, pred, procs=(), cap_s=CAP_S):
    """Waits for pred() to hold; fails if one of `procs` exits first or the cap passes."""
    end = time.monotonic() + cap_s
    while not pred():
        for p in procs:
            if p.poll() is not None:
                raise Failure(f"{what}: {os.path.basename(p.args[0])} exited ({p.rc}) first:\n{p.log()[-3000:]}")
        if time.monotonic() > end:
            raise Failure(f"{what}: not within {cap_s} s")
        time.sleep(0.02)


# --- SIRAD/1 --------------------------------------------------------------------------------

def header_type(cmd):
    return {"hello": pb.Hello, "welcome": pb.Welcome, "scene": pb.SceneChunk, "ready": pb.Ready, "grant": pb.Grant,
            "report": pb.Report, "update": pb.Update, "stop": pb.Stop, "final": pb.Report, "error": pb.Error,
            "image": pb.Image, "tiles": pb.Grant, "pixels": pb.Pixels}.get(cmd)


def encode(cmd, header=None, bulk=()):
    return [SIG, bytes([CMD[cmd]]), header.SerializeToString() if header is not None else b""] + list(bulk)


def decode(frames):
    check(len(frames) >= 3 and frames[0] == SIG and len(frames[1]) == 1, f"not a SIRAD/1 message: {frames[:2]}")
    cmd = NAME[frames[1][0]]
    t = header_type(cmd)
    header = t.FromString(frames[2]) if t else None
    return cmd, header, frames[3:]


class Peer:
    """A SIRAD/1 node written here: a DEALER to the coordinator."""

    def __init__(self, ctx, endpoint, name):
        self.s = ctx.socket(zmq.DEALER)
        self.s.setsockopt(zmq.LINGER, 0)
        self.s.setsockopt(zmq.SNDHWM, 100000)
        self.s.connect(endpoint)
        self.name = name
        self.run = None

    def send(self, cmd, header=None, bulk=()):
        self.s.send_multipart(encode(cmd, header, bulk))

    def recv(self, timeout_ms):
        if self.s.poll(timeout_ms) == 0:
            return None
        return decode(self.s.recv_multipart())

    def hello(self):
        h = pb.Hello(node_name=self.name, sirad_version="hostile", max_message_bytes=1 << 30)
        self.send("hello", h)

    def wait_grant(self, coordinator):
        """The next GRANT's header; fails if the coordinator exits first."""
        while True:
            check(coordinator.poll() is None, f"the coordinator ended before {self.name}'s grant")
            m = self.recv(100)
            if m is not None and m[0] == "grant":
                return m[1]

    def idle_until_exit(self, coordinator):
        """Heartbeats (running nothing, reading what comes) until the coordinator exits; the
        commands it received, in order."""
        seen = []
        while coordinator.poll() is None:
            m = self.recv(100)
            if m is not None:
                seen.append(m[0])
            self.send("heartbeat")
        return seen

    def join(self, procs, ms_per_bundle=1.0):
        """HELLO, WELCOME, the SCENE chunks, READY: as a node joins, without running anything.
        Asked to say HELLO again (an ERROR: a farm starting a job for it), it does, and from then
        on heartbeats while it waits, as a farm's node must to stay known."""
        self.hello()
        asked = False
        end = time.monotonic() + CAP_S
        while True:
            check(time.monotonic() < end, f"{self.name}: no WELCOME and SCENE")
            for p in procs:
                check(p.poll() is None, f"{p.args[0]} exited while {self.name} joined:\n{p.log()[-3000:]}")
            m = self.recv(100)
            if m is None:
                if asked:
                    self.send("heartbeat")
                continue
            cmd, h, _ = m
            if cmd == "error":
                asked = True
                self.hello()
            elif cmd == "welcome" and h.HasField("run"):
                self.run = h.run
            elif cmd == "scene" and h.last:
                self.send("ready", pb.Ready(run_id=self.run.run_id, scene_hash=self.run.scene_hash,
                                            ms_per_bundle=ms_per_bundle))
                return


# --- outputs --------------------------------------------------------------------------------

def ply_radiosity(path):
    """Per-face radiosity (r, g, b) of sirad's binary PLY."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    elements, current = [], None
    for line in data[:end].decode().splitlines():
        w = line.split()
        if w[0] == "element":
            current = (w[1], int(w[2]), [])
            elements.append(current)
        elif w[0] == "property":
            current[2].append(w[1:])
    sizes = {"float": 4, "uchar": 1, "int": 4, "uint": 4}
    fmt = {"float": "f", "uchar": "B", "int": "i", "uint": "I"}
    at, out = end, []
    for name, count, props in elements:
        for _ in range(count):
            row = {}
            for p in props:
                if p[0] == "list":
                    (n,) = struct.unpack_from("<" + fmt[p[1]], data, at)
                    at += sizes[p[1]] + n * sizes[p[2]]
                else:
                    (row[p[1]],) = struct.unpack_from("<" + fmt[p[0]], data, at)
                    at += sizes[p[0]]
            if name == "face":
                out.append((row["radiosity_r"], row["radiosity_g"], row["radiosity_b"]))
    return out


def ledger_ranges(path):
    rows = []
    with open(path) as f:
        next(f)
        for line in f:
            node, rest = line.split(",", 1)
            name, first, last = rest.rsplit(",", 2)
            rows.append((int(node), name.strip('"'), int(first), int(last)))
    return rows


def read_status(path):
    import json
    with open(path) as f:
        return json.load(f)


# --- a run ----------------------------------------------------------------------------------

class Run:
    """A coordinator on the furnace (300 patches, the plain transport with random directions, so
    the tolerance below holds) over loopback TCP, and honest node processes. Heartbeats every
    200 ms, and a peer silent for 25 of them (5 s) is dead: a window that a loaded machine's
    stalls (a process not scheduled, a slow disk) stay well inside, since an honest node declared
    dead fails every case."""

    def __init__(self, build, work, bundles, min_nodes, extra=(), insecure=True, size=(16, 16), timeout=300):
        self.build, self.work, self.bundles = build, work, bundles
        self.endpoint_file = os.path.join(work, "endpoint")
        self.out = os.path.join(work, "furnace")
        self.ledger = os.path.join(work, "ledger.csv")
        self.status = os.path.join(work, "status.json")
        args = [os.path.join(build, "sirad-coordinator"), "furnace", "--listen", "tcp://127.0.0.1:*"] + \
               (["--insecure"] if insecure else []) + ["--endpoint-file", self.endpoint_file, "--bundles", str(bundles), "--patches", "300",
                "--min-nodes", str(min_nodes), "--control-variate", "off", "--directions", "random",
                "--shots-per-bundle", "0", "--exchange-every", "16", "--out", self.out, "--width", str(size[0]),
                "--height", str(size[1]), "--ledger", self.ledger, "--status-json", self.status, "--timeout", str(timeout),
                "--heartbeat-ms", "200", "--liveness", "25", "-q"] + list(extra)
        self.coordinator = Proc(args, os.path.join(work, "coordinator.log"))
        wait_until("the endpoint file", lambda: os.path.exists(self.endpoint_file) and os.path.getsize(self.endpoint_file) > 0,
                   [self.coordinator])
        with open(self.endpoint_file) as f:
            self.endpoint = f.read().strip()
        self.nodes = []

    def honest(self, n):
        for i in range(n):
            name = f"h{len(self.nodes)}"
            self.nodes.append(Proc([os.path.join(self.build, "sirad-node"), "--connect", self.endpoint, "--name", name,
                                    "--insecure"], os.path.join(self.work, f"{name}.log")))

    def finish(self):
        rc = self.coordinator.wait()
        for n in self.nodes:
            n.stop()
        return rc

    def check_result(self, honest_names):
        """rc 0; every index in the ledger once, run by honest nodes only; no honest node dead or
        quarantined; the furnace's mean radiosity 2 within 4 sd of a K-bundle chain average: the
        sd of one 1024-bundle average of the mean is 0.0097 for this setting (tests/processes_test
        .cpp), so 0.0097 sqrt(1024 / K) 4."""
        log = self.coordinator.log()
        check(self.coordinator.rc == 0, f"coordinator exit {self.coordinator.rc}:\n{log[-4000:]}")
        rows = ledger_ranges(self.ledger)
        covered = sorted((first, last) for _, _, first, last in rows)
        at = 0
        for first, last in covered:
            check(first == at, f"ledger: gap or overlap at {at} (next range [{first}, {last}))")
            at = last
        check(at == self.bundles, f"ledger ends at {at}, not {self.bundles}")
        check(all(name in honest_names for _, name, _, _ in rows), f"ledger names a dishonest node: {rows}")
        status = read_status(self.status)
        for n in status["nodes"]:
            if n["name"] in honest_names:
                check(n["state"] == "done", f"honest node {n['name']} ended {n['state']} ({n.get('why', '')})")
        radiosity = ply_radiosity(self.out + ".ply")
        mean = sum(r for r, _, _ in radiosity) / len(radiosity)
        tol = 0.0097 * math.sqrt(1024 / self.bundles) * 4
        print(f"furnace mean {mean:.4f} (tolerance {tol:.4f}); coordinator peak {self.coordinator.maxrss_kib / 1024:.0f} MiB")
        check(abs(mean - 2.0) <= tol, f"furnace mean {mean} is not 2 within {tol}")
        return log


# --- the cases ------------------------------------------------------------------------------

def case_control(build, work, ctx):
    """No attack: the reference figures (peak memory) for the bounds below."""
    run = Run(build, work, 2048, 2)
    run.honest(2)
    run.finish()
    run.check_result({"h0", "h1"})


def case_frame_flood(build, work, ctx):
    """Class 1: messages of many frames. A peer sends 4 messages of 2,048 frames of 64 KiB (128
    MiB each, every frame under ZMQ_MAXMSGSIZE) as REPORTs. libzmq holds a message whole before
    any part can be read and has no bound on frames per message; the coordinator's PeerBytes
    (proto/peer_bytes.h) shuts the connection down once libzmq holds more than
    max_peer_bytes for it (4.3 MiB for 300 patches), long before a message is whole: each
    message ends as a shut connection (pyzmq connects again and sends the next), none is ever
    read. The peak is the coordinator's own (23 MiB in the control case) plus the bound plus
    what loopback carries in one 10 ms check: bound 100 MiB. Before the bound on bytes per
    peer: 146 MiB (each message read whole and refused by its command's bound); before that
    bound too, 693 MiB."""
    run = Run(build, work, 2048, 2)
    p = Peer(ctx, run.endpoint, "flood")
    frame = b"\0" * 65536
    for _ in range(4):
        p.s.send_multipart([SIG, bytes([CMD["report"]]), b""] + [frame] * 2048)
    wait_until("the flood's connections shut", lambda: run.coordinator.log().count("connection shut: libzmq held") >= 4,
               [run.coordinator])
    run.honest(2)
    run.finish()
    log = run.check_result({"h0", "h1"})
    peak = run.coordinator.maxrss_kib / 1024
    check(peak < 100, f"coordinator peak {peak:.0f} MiB, over 100 MiB")
    check("over the bound of its command" not in log, "a flood message was read whole")


def case_big_hello(build, work, ctx):
    """Class 1: one frame of 512 MiB (a HELLO). The coordinator's largest frame for 300 patches is
    a header or one chunk plus 64 KiB (128 KiB), so libzmq ends the connection at the frame's
    length: the coordinator never holds it. Peak bound: the control's 23 MiB, with slack, 60 MiB.
    (The frame limit already refused this before the bound of class 1; a regression check.)"""
    run = Run(build, work, 2048, 2)
    p = Peer(ctx, run.endpoint, "big")
    p.s.send_multipart([SIG, bytes([CMD["hello"]]), b"\0" * (512 << 20)])
    p.s.close()
    run.honest(2)
    run.finish()
    run.check_result({"h0", "h1"})
    peak = run.coordinator.maxrss_kib / 1024
    check(peak < 60, f"coordinator peak {peak:.0f} MiB, over 60 MiB")


def case_never_reports(build, work, ctx):
    """Class 2: a node that joins, takes its grant, heartbeats, and never reports. The run waits
    for it (--min-nodes 3), so it holds a grant; due at first after its bound, the first grant's
    30 s and the 10 s least slack, the grant is brought forward when an honest node reports its
    own first grant (16 times what that one took, plus the slack: tighten_first_grants); it
    passes, the sleeper is declared dead, its grant goes back to the budget and the honest
    nodes run it: the run ends with every bundle."""
    run = Run(build, work, 2048, 3)
    p = Peer(ctx, run.endpoint, "sleeper")
    run.honest(2)
    p.join([run.coordinator])
    check("grant" in p.idle_until_exit(run.coordinator), "the sleeper never got a grant")
    run.finish()
    log = run.check_result({"h0", "h1"})
    check("first grants now due within" in log, f"the sleeper's grant was not brought forward:\n{log[-3000:]}")
    check("sleeper: declared dead (grant" in log and "overdue" in log, f"no overdue grant in the log:\n{log[-3000:]}")
    status = read_status(run.status)
    check(any(n["name"] == "sleeper" and n["state"] == "dead" and n.get("why", "").startswith("grant ") and "overdue" in n["why"]
              for n in status["nodes"]), f"sleeper not dead of its overdue grant: {status}")


def case_status_write_fails(build, work, ctx):
    """Class 5: --status-json cannot be written mid-run (a directory takes its place): the run
    goes on, says so once, and ends with rc 0 and its outputs."""
    run = Run(build, work, 2048, 2)
    wait_until("the first status", lambda: os.path.exists(run.status), [run.coordinator])
    os.remove(run.status)
    os.mkdir(run.status)
    run.honest(2)
    rc = run.finish()
    log = run.coordinator.log()
    check(rc == 0, f"coordinator exit {rc}:\n{log[-3000:]}")
    check("--status-json not written" in log, f"no warning:\n{log[-3000:]}")
    for ext in (".exr", ".png", ".ply"):
        check(os.path.exists(run.out + ext), f"no {ext}")
    os.rmdir(run.status)


def case_damaged_checkpoint(build, work, ctx):
    """Class 4: a checkpoint with one flipped bit (the golden run's, tests/data/golden) is refused
    by --resume with one line naming the file, and nothing runs."""
    src = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "golden", "resume.ckpt")
    with open(src, "rb") as f:
        data = bytearray(f.read())
    for at in (0, 9, 15, len(data) // 2, len(data) - 1):
        bad = os.path.join(work, f"flip{at}.ckpt")
        flipped = bytearray(data)
        flipped[at] ^= 0x10
        with open(bad, "wb") as f:
            f.write(flipped)
        c = Proc([os.path.join(build, "sirad-coordinator"), "cornell", "--resume", bad, "--listen", "tcp://127.0.0.1:*",
                  "--insecure", "-q"], os.path.join(work, f"resume{at}.log"))
        rc = c.wait(60)
        log = c.log().strip()
        check(rc != 0, f"flip at byte {at} resumed")
        check(len(log.splitlines()) == 1 and bad in log, f"flip at byte {at}: not one line naming the file: {log}")


def case_lying_welcome(build, work, ctx):
    """Class 6: a coordinator (a ROUTER here) that sends a real sirad-node WELCOMEs no run can
    have: chunk starts past the patches or out of order, grid 100,000, burn-in 2^31 - 1, more
    patches than the node takes. The node refuses each (ERROR naming it), stays up, and answers
    the next; then a 3-frame UPDATE of 3 x 120 MiB (over the node's 96 MiB frame limit: libzmq
    ends the connection for good, and the node starts a fresh socket after 16 s of silence). The
    node's peak stays under 200 MiB (its
    OpenCL set-up: under 120 MiB here) and it still says HELLO after all of it."""
    router = ctx.socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    node = Proc([os.path.join(build, "sirad-node"), "--connect", f"tcp://127.0.0.1:{port}", "--name", "victim", "--insecure"],
                os.path.join(work, "node.log"))

    def next_message(want):
        end = time.monotonic() + CAP_S
        while time.monotonic() < end:
            check(node.poll() is None, f"the node exited ({node.rc}):\n{node.log()[-3000:]}")
            if router.poll(100):
                frames = router.recv_multipart()
                cmd, h, bulk = decode(frames[1:])
                if cmd == want:
                    return frames[0], h
        raise Failure(f"no {want} from the node")

    ident, _ = next_message("hello")

    def run_of(**fields):
        r = pb.Run(run_id=7, scene_hash="0" * 32, seed=1, grid=0, rule="chain", burn_in=0, patches=300,
                   exchange_every=16, exchange_fraction=1.0, topology="star", mode="async", bundles=64)
        r.chunk_starts.extend(fields.pop("chunk_starts", [0, 100, 200]))
        for k, v in fields.items():
            setattr(r, k, v)
        return r

    lies = [("chunk_starts", run_of(chunk_starts=[0, 5000]), "chunk 1 starts"),
            ("chunk order", run_of(chunk_starts=[0, 300, 100]), "chunk 1 starts"),
            ("grid", run_of(grid=100000), "grid 100000"),
            ("burn-in", run_of(burn_in=2**31 - 1), "burn-in"),
            ("patches", run_of(patches=50_000_000, chunk_starts=[0]), "at most"),
            ("rule", run_of(rule="magic"), "rule")]
    for what, run, expect in lies:
        w = pb.Welcome(node_index=0, heartbeat_ms=1000, liveness=3)
        w.run.CopyFrom(run)
        router.send_multipart([ident] + encode("welcome", w))
        _, e = next_message("error")
        check("WELCOME refused" in e.reason and expect in e.reason, f"{what}: the node said {e.reason!r}")
    big = b"\0" * (120 << 20)
    router.send_multipart([ident] + encode("update", pb.Update(run_id=7, chunks=[0, 1, 2], counts=[1, 1, 1]), [big] * 3))
    del big
    ident, _ = next_message("hello")  # from its fresh socket
    node.stop()
    peak = node.maxrss_kib / 1024
    print(f"node peak {peak:.0f} MiB")
    check(peak < 200, f"node peak {peak:.0f} MiB, over 200 MiB")


def case_huge_emission(build, work, ctx):
    """Class 3: an emission of 1e38 (which gave an all-NaN PLY with exit 0 on one node, a
    quarantined local node with --nodes 2, and a run stuck at 0 bundles over TCP). Refused at
    meshing in every mode with one line naming the scene and the bound; no output is written.
    1e20, the bound, runs and gives finite radiosity."""
    obj = os.path.join(work, "hot.obj")
    with open(obj, "w") as f:
        f.write("mtllib hot.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\n"
                "usemtl wall\nf 1 2 3\nf 1 3 4\nusemtl hot\nf 1 5 6\nf 1 6 2\n")
    for ke, ok in (("1e38", False), ("1e20", True)):
        with open(os.path.join(work, "hot.mtl"), "w") as f:
            f.write(f"newmtl wall\nKd 0.5 0.5 0.5\nnewmtl hot\nKd 0.5 0.5 0.5\nKe {ke} {ke} {ke}\n")
        sirad, coord = os.path.join(build, "sirad"), os.path.join(build, "sirad-coordinator")
        modes = [("one node", [sirad, "render", obj, "--bundles", "64", "--two-sided"]),
                 ("--nodes 2", [sirad, "render", obj, "--bundles", "64", "--two-sided", "--nodes", "2"]),
                 ("coordinator", [coord, obj, "--bundles", "64", "--two-sided", "--listen", "tcp://127.0.0.1:*",
                                  "--insecure", "--timeout", "60"])]
        for mode, args in modes:
            out = os.path.join(work, f"out-{ke}-{mode.replace(' ', '')}")
            if ok and mode == "coordinator":
                continue  # a coordinator without nodes waits: the two embedded modes cover the run
            p = Proc(args + ["--out", out, "--width", "8", "--height", "8", "-q"], out + ".log")
            rc = p.wait(120)
            log = p.log().strip()
            if ok:
                check(rc == 0, f"Ke {ke}, {mode}: exit {rc}: {log[-2000:]}")
                values = ply_radiosity(out + ".ply")
                check(all(math.isfinite(v) for r in values for v in r), f"Ke {ke}, {mode}: a non-finite radiosity")
            else:
                errors = [l for l in log.splitlines() if "error" in l]
                check(rc != 0, f"Ke {ke}, {mode}: exit 0")
                check(len(errors) == 1 and "emission component 0 is 1e+38, outside [0, 1e+20]" in errors[0],
                      f"Ke {ke}, {mode}: not one clear error: {log}")
                left = [e for e in (".exr", ".png", ".ply", ".glb") if os.path.exists(out + e)]
                check(not left, f"Ke {ke}, {mode}: wrote {left}")


def case_garbage_flood(build, work, ctx):
    """Class 16: 20,000 garbage messages from one peer in a burst. Each is refused, but the log
    says so at most 5 times per peer per 10 s (the next line, or the end of the run, counts what
    was held back): here
    at most 5 x (the run's seconds / 10 + 1) lines about it, not 20,000; the run is unharmed."""
    run = Run(build, work, 2048, 2)
    p = Peer(ctx, run.endpoint, "garbage")
    for i in range(20000):
        p.s.send_multipart([b"JUNK", bytes([i & 0xff]), b"x" * (i % 97)])
    p.send("heartbeat")  # one more, known to come after the burst
    run.honest(2)
    t0 = time.monotonic()
    run.finish()
    seconds = time.monotonic() - t0
    log = run.check_result({"h0", "h1"})
    lines = log.count("sirad-coordinator: unknown peer: ")
    allowed = 5 * (int(seconds / 10) + 2)
    print(f"{lines} log lines about the flood in {seconds:.1f} s (at most {allowed})")
    check(lines <= allowed, f"{lines} log lines about 20,000 garbage messages (at most {allowed})")
    check("held back" in log, "no count of the held-back lines")


def keypair(build, work, name):
    subprocess.run([os.path.join(build, "sirad"), "keygen", os.path.join(work, name)], check=True, capture_output=True)

    def key(path, field):
        with open(path) as f:
            for line in f:
                if line.strip().startswith(field):
                    return line.split('"')[1].encode()
        raise Failure(f"no {field} in {path}")
    pub = os.path.join(work, name + ".key")
    return key(pub, "public-key"), key(pub + "_secret", "secret-key")


def case_stolen_routing_id(build, work, ctx):
    """Class 10: under CURVE, node B (an allowed key) takes node A's routing id and sends a NaN
    REPORT for A's grant. The coordinator binds a peer to its key (the ZAP user id): B's
    message is refused and A is not quarantined (it ends dead, by its grant deadline, since this
    A is a Python peer that runs nothing); the honest nodes finish the run."""
    cpub, csec = keypair(build, work, "coordinator")
    keys = {n: keypair(build, work, n) for n in ("h0", "h1", "a", "b")}
    with open(os.path.join(work, "allow"), "w") as f:
        for n, (pub, _) in keys.items():
            f.write(f"{pub.decode()} {n}\n")
    extra = ["--curve-secret", os.path.join(work, "coordinator.key_secret"), "--allow", os.path.join(work, "allow")]
    run = Run(build, work, 2048, 3, extra, insecure=False)

    def curve_peer(name, routing_id):
        pub, sec = keys[name]
        s = ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.CURVE_SERVERKEY, cpub)
        s.setsockopt(zmq.CURVE_PUBLICKEY, pub)
        s.setsockopt(zmq.CURVE_SECRETKEY, sec)
        s.setsockopt(zmq.ROUTING_ID, routing_id)
        s.connect(run.endpoint)
        p = Peer.__new__(Peer)
        p.s, p.name, p.run = s, name, None
        return p

    for i in range(2):
        name = f"h{i}"
        run.nodes.append(Proc([os.path.join(build, "sirad-node"), "--connect", run.endpoint, "--name", name, "--curve-secret",
                               os.path.join(work, name + ".key_secret"), "--server-key", os.path.join(work, "coordinator.key")],
                              os.path.join(work, f"{name}.log")))
    a = curve_peer("a", b"node-shared")
    a.join([run.coordinator])
    grant = a.wait_grant(run.coordinator)
    b = curve_peer("b", b"node-shared")
    nan = struct.pack("<d", float("nan")) * (3 * 300)
    r = pb.Report(run_id=grant.run_id, grant_id=grant.grant_id, chunks=[0], counts=[1])
    r.done.extend(grant.ranges)
    b.send("report", r, [nan[:24 * 19]])
    wait_until("B's refusal", lambda: "from another key: refused" in run.coordinator.log(), [run.coordinator])
    a.idle_until_exit(run.coordinator)
    run.finish()
    run.check_result({"h0", "h1"})
    status = read_status(run.status)
    states = {n["name"]: n["state"] for n in status["nodes"]}
    check(states.get("a") != "quarantined", f"A was quarantined: {states}")


def case_bad_files_and_flags(build, work, ctx):
    """Classes 11, 14 and 15: every file a command reads is opened only when it is a regular
    file within a bound (a device or a FIFO is refused at once, never read for ever or waited
    on); outputs that name a directory are refused before the run; bounds read plainly."""
    fifo = os.path.join(work, "fifo")
    os.mkfifo(fifo)
    os.mkdir(os.path.join(work, "dir"))
    coord, sirad, node = (os.path.join(build, b) for b in ("sirad-coordinator", "sirad", "sirad-node"))
    big_profile = os.path.join(work, "big.yaml")
    with open(big_profile, "w") as f:
        f.write("nodes:\n" + "".join(f"  - index: {i}\n    speed: 1\n" for i in range(5000)))
    sec = os.path.join(work, "k")
    subprocess.run([sirad, "keygen", sec], check=True, capture_output=True)
    cases = [
        ([coord, "cornell", "--allow", "/dev/zero", "--curve-secret", sec + ".key_secret"], "not a regular file"),
        ([coord, "cornell", "--allow", fifo, "--curve-secret", sec + ".key_secret"], "not a regular file"),
        ([coord, "cornell", "--resume", "/dev/zero"], "not a regular file"),
        ([coord, "cornell", "--profile", fifo], "not a regular file"),
        ([coord, "cornell", "--profile", big_profile, "--check-config"], "5000 entries (at most 4096"),
        ([node, "--connect", "tcp://127.0.0.1:9", "--curve-secret", "/dev/zero", "--server-key", sec + ".key"], "/dev/zero"),
        ([node, "--connect", "tcp://127.0.0.1:9", "--curve-secret", sec + ".key_secret", "--server-key", fifo], "not a regular file"),
        ([coord, "cornell", "--insecure", "--checkpoint", os.path.join(work, "dir"), "--check-config"], "is a directory"),
        ([coord, "cornell", "--insecure", "--ledger", os.path.join(work, "dir"), "--check-config"], "is a directory"),
        ([sirad, "render", "cornell", "--out", os.path.join(work, "dir") + "/"], "names a directory"),
        ([sirad, "keygen", ""], "empty output name"),
        ([sirad, "render", "cornell", "--max-edge", "0"], "must be greater than 0 (got 0)"),
        ([coord, "cornell", "--timeout", "-1"], "must be 0 or more (got -1)"),
    ]
    for i, (args, expect) in enumerate(cases):
        p = Proc(args, os.path.join(work, f"case{i}.log"))
        rc = p.wait(60)
        log = p.log().strip()
        err = [l for l in log.splitlines() if "error" in l]
        check(rc != 0, f"{args[1:]}: exit 0")
        check(len(err) == 1 and expect in err[0] and len(err[0]) < 300, f"{args[1:]}: not one clear line with {expect!r}: {log}")
    check(not os.listdir(os.path.join(work, "dir")), "something was written into the directory")


def case_join_cycles(build, work, ctx):
    """Class 7: one peer sends 30,000 HELLO + READY pairs (each HELLO after a READY makes the
    coordinator declare the last entry dead and join it anew). Joins are limited to 256 per
    address in 10 s, and a joined node's chunk states are allocated only when it sends one, so
    the node entries stay few and small and the log says so a few times: at most 300 + 256 x
    (the run's seconds / 10) entries in the status, at most 20 "declared dead" lines, and the
    coordinator's peak under 60 MiB (23 MiB in the control case; before, 479 MB after 30,000
    cycles). The honest nodes finish the run."""
    run = Run(build, work, 4096, 2)
    p = Peer(ctx, run.endpoint, "cycler")
    p.join([run.coordinator])
    ready = pb.Ready(run_id=p.run.run_id, scene_hash=p.run.scene_hash, ms_per_bundle=1.0)
    hello = encode("hello", pb.Hello(node_name="cycler", sirad_version="hostile"))
    ready_frames = encode("ready", ready)
    t0 = time.monotonic()
    for _ in range(30000):
        p.s.send_multipart(hello)
        p.s.send_multipart(ready_frames)
    p.send("heartbeat")
    run.honest(2)
    run.finish()
    seconds = time.monotonic() - t0
    log = run.check_result({"h0", "h1"})
    status = read_status(run.status)
    entries = len(status["nodes"])
    dead_lines = log.count("declared dead")
    peak = run.coordinator.maxrss_kib / 1024
    print(f"{entries} node entries, {dead_lines} 'declared dead' lines in {seconds:.1f} s; peak {peak:.0f} MiB")
    check(entries <= 300 + 256 * (seconds / 10), f"{entries} node entries")
    check(dead_lines <= 20, f"{dead_lines} 'declared dead' lines")
    check(peak < 60, f"coordinator peak {peak:.0f} MiB, over 60 MiB")


def case_join_cycles_many_addresses(build, work, ctx):
    """Class 7: the join limit is per address, so a peer with many addresses (here 20 loopback
    addresses, 127.0.0.10 to .29, each 600 HELLO + READY pairs: 5,120 joins the limit lets
    through in 10 s, 4 times that refused) could still grow the node entries. They are capped:
    at Policy::kMaxNodeEntries (4096) a new node takes the index of the oldest departed entry
    that holds nothing, so the status lists exactly 4096 entries at the end, the honest nodes
    (joining last) finish the run, and the coordinator's peak stays under 100 MiB (23 in the
    control case; an entry costs about 1 KB)."""
    run = Run(build, work, 4096, 2)
    first = Peer(ctx, run.endpoint, "cycler")
    first.join([run.coordinator])
    port = run.endpoint.rsplit(":", 1)[1]
    hello = encode("hello", pb.Hello(node_name="cycler", sirad_version="hostile"))
    ready = encode("ready", pb.Ready(run_id=first.run.run_id, scene_hash=first.run.scene_hash, ms_per_bundle=1.0))
    peers = []
    for a in range(10, 30):
        s = ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.SNDHWM, 100000)
        s.connect(f"tcp://127.0.0.{a}:0;127.0.0.1:{port}")
        peers.append(s)
    t0 = time.monotonic()
    for _ in range(600):
        for s in peers:
            s.send_multipart(hello)
            s.send_multipart(ready)
    run.honest(2)
    run.finish()
    seconds = time.monotonic() - t0
    run.check_result({"h0", "h1"})
    entries = len(read_status(run.status)["nodes"])
    peak = run.coordinator.maxrss_kib / 1024
    print(f"{entries} node entries after 12,000 HELLO + READY pairs from 20 addresses in {seconds:.1f} s; peak {peak:.0f} MiB")
    check(entries == 4096, f"{entries} node entries, not the cap of 4096")
    check(peak < 100, f"coordinator peak {peak:.0f} MiB, over 100 MiB")


def case_name_injection(build, work, ctx):
    """Class 9: a node whose HELLO name carries a newline, a forged log line and ANSI escapes.
    Names reach the log, the summary and the status as printable ASCII only: no line of the
    coordinator's output starts with the forged text, and no escape byte is printed."""
    run = Run(build, work, 2048, 3)
    forged = "x\nsirad-coordinator: h0: quarantined: forged\x1b[2J\x1b[1;1H"
    p = Peer(ctx, run.endpoint, forged)
    run.honest(2)
    p.join([run.coordinator])
    p.idle_until_exit(run.coordinator)
    run.finish()
    log = run.check_result({"h0", "h1"})
    check(not any(l.startswith("sirad-coordinator: h0: quarantined") for l in log.splitlines()), "a forged line")
    check("\x1b" not in log, "an escape byte reached the log")
    status = read_status(run.status)
    check(any(n["name"].startswith("x?sirad-coordinator") for n in status["nodes"]), f"the name not as printable ASCII: {status}")


def case_foreign_run_report(build, work, ctx):
    """Class 13: a node reports its grant's bundles done under another run's id. No honest node
    does that: it is quarantined, and nothing of the report counts (its done ranges least of
    all: before, they entered the ledger with no samples); the honest nodes run every bundle."""
    run = Run(build, work, 2048, 3)
    p = Peer(ctx, run.endpoint, "foreign")
    run.honest(2)
    p.join([run.coordinator])
    grant = p.wait_grant(run.coordinator)
    r = pb.Report(run_id=grant.run_id ^ 0xFFFF, grant_id=grant.grant_id)
    r.done.extend(grant.ranges)
    p.send("report", r)
    p.idle_until_exit(run.coordinator)
    run.finish()
    run.check_result({"h0", "h1"})  # the ledger: every index once, by honest nodes only
    status = read_status(run.status)
    check(any(n["name"] == "foreign" and n["state"] == "quarantined" for n in status["nodes"]), f"not quarantined: {status}")


class LyingProxy:
    """A real sirad-node that lies: the node connects to this proxy (a ROUTER on loopback), which
    passes every message between it and the coordinator (a DEALER) unchanged, except those that
    `lie` (frames -> frames, or None to pass them as they are) rewrites."""

    def __init__(self, ctx, coordinator_endpoint, lie):
        import threading
        self.lie = lie
        self.front = ctx.socket(zmq.ROUTER)
        self.front.setsockopt(zmq.LINGER, 0)
        port = self.front.bind_to_random_port("tcp://127.0.0.1")
        self.endpoint = f"tcp://127.0.0.1:{port}"
        self.back = ctx.socket(zmq.DEALER)
        self.back.setsockopt(zmq.LINGER, 0)
        self.back.connect(coordinator_endpoint)
        self.lied = 0
        self.crashed = False  # set (by heard()): from then on nothing passes either way
        self.stopping = False
        self.thread = threading.Thread(target=self.loop, daemon=True)
        self.thread.start()

    def heard(self, frames):
        """A message from the coordinator, before it is passed on (a subclass may crash on it)."""

    def loop(self):
        poller = zmq.Poller()
        poller.register(self.front, zmq.POLLIN)
        poller.register(self.back, zmq.POLLIN)
        node = None
        while not self.stopping:
            for sock, _ in poller.poll(50):
                if sock is self.front:
                    node, *frames = self.front.recv_multipart()
                    lied = self.lie(frames)
                    if lied is not None:
                        frames = lied
                        self.lied += 1
                    if not self.crashed:
                        self.back.send_multipart(frames)
                else:
                    frames = self.back.recv_multipart()
                    self.heard(frames)
                    if node is not None and not self.crashed:
                        self.front.send_multipart([node] + frames)

    def stop(self):
        self.stopping = True
        self.thread.join(10)


def scaled_sums(factor):
    """The chunk sums of REPORTs and FINAL multiplied by `factor` (0: zeros): the lie has the
    batch structure of an honest chain, scaled (the plausible lie of class 17)."""
    import array

    def lie(frames):
        if len(frames) <= 3 or frames[0] != SIG or frames[1][0] not in (CMD["report"], CMD["final"]):
            return None
        out = frames[:3]
        for f in frames[3:]:
            values = array.array("d")
            values.frombytes(f)
            out.append(array.array("d", (v * factor for v in values)).tobytes())
        return out
    return lie


def run_with_liar(run, ctx, lie, honest):
    """`honest` honest nodes and a real node named "liar" behind a LyingProxy (`lie`) in `run`,
    until the run ends; the proxy (how often it lied)."""
    proxy = LyingProxy(ctx, run.endpoint, lie)
    run.honest(honest)
    liar = Proc([os.path.join(run.build, "sirad-node"), "--connect", proxy.endpoint, "--name", "liar", "--insecure"],
                os.path.join(run.work, "liar.log"))
    try:
        run.finish()
    finally:
        liar.stop()
        proxy.stop()
    return proxy


def lying_node_case(build, work, ctx, factor, honest, what):
    """Class 17: `honest` honest nodes and a real node behind a LyingProxy (`factor`). The liar
    is quarantined for `what` (the reason in the log: the scene's bound, or the median of the
    nodes; plausibility.h derives both), its bundles run again on the honest nodes, and the
    furnace comes out right (check_result: every index once, by honest nodes, the mean 2 within
    its tolerance, no honest node quarantined). The coordinator's peak stays under 60 MiB (23 in
    the control case)."""
    run = Run(build, work, 4096, honest + 1)
    proxy = run_with_liar(run, ctx, scaled_sums(factor), honest)
    log = run.check_result({f"h{i}" for i in range(honest)})
    status = read_status(run.status)
    liars = [n for n in status["nodes"] if n["name"] == "liar"]
    check(liars and liars[0]["state"] == "quarantined", f"the liar was not quarantined: {liars}")
    check(what in liars[0]["why"], f"the liar was quarantined for something else: {liars[0]['why']}")
    honest_suspicion = max(n["suspicion"] for n in status["nodes"] if n["name"] != "liar")
    peak = run.coordinator.maxrss_kib / 1024
    print(f"liar x{factor}: {proxy.lied} lying messages; quarantined: {liars[0]['why']}; "
          f"honest nodes' largest suspicion {honest_suspicion:.3f}; coordinator peak {peak:.0f} MiB")
    check(honest_suspicion < 1, "an honest node's score is over 1")
    check(peak < 60, f"coordinator peak {peak:.0f} MiB, over 60 MiB")


def case_liar_x1000(build, work, ctx):
    """Class 17: a node whose sums are 1000 times its chain's, beside two honest nodes: far from
    the median of the three (and beyond the furnace's bound, B <= 2)."""
    lying_node_case(build, work, ctx, 1000.0, 2, "chunk ")


def case_liar_zero(build, work, ctx):
    """Class 17: a node that sends zeros for its sums (with its true counts), beside two honest
    nodes: below the furnace's emission, E = 1, and far from the median."""
    lying_node_case(build, work, ctx, 0.0, 2, "chunk ")


def case_liar_x1000_of_two(build, work, ctx):
    """Class 17: one honest node and one that sends 1000 times its sums: no median of two can say
    which lies, but the scene's bound can (the furnace's radiosity is at most 2)."""
    lying_node_case(build, work, ctx, 1000.0, 1, "above what the scene allows")


def case_liar_small_bias(build, work, ctx):
    """Class 17: a node whose sums are 0.8 times its chain's (the furnace at 1.6, within the
    scene's bounds [1, 2]), beside two honest nodes: caught by the median of the three once it
    is 12 standard errors off, which the honest spread of this setting reaches after a few
    hundred bundles of each node (plausibility.h)."""
    lying_node_case(build, work, ctx, 0.8, 2, "the median of 3 nodes")


def lying_pixels_case(build, work, ctx, lie, what):
    """Class 18: the image phase (PROTOCOL.md section 3.4). An honest node and a real node behind
    a LyingProxy whose PIXELS `lie` rewrites render the furnace's final gather (96 x 64, 6 tiles
    of 32 px). The liar is dropped from the image for `what` at its first PIXELS, nothing of
    that message is placed, its tiles are granted again to the honest node, and the run's image
    is the one `sirad image` renders from the run's PLY on one machine (the PNGs byte for byte)."""
    pixels_cmd = CMD["pixels"]
    first = {"done": False}

    def once(frames):
        if first["done"] or len(frames) < 3 or frames[0] != SIG or frames[1][0] != pixels_cmd:
            return None
        first["done"] = True
        return lie(frames)

    run = Run(build, work, 1024, 2, ["--final-gather", "4"], size=(96, 64))
    proxy = run_with_liar(run, ctx, once, 1)
    log = run.check_result({"h0", "liar"})  # the liar ran its bundles honestly
    check(proxy.lied == 1, f"{proxy.lied} lying PIXELS (the liar was granted no tiles?)")
    check(f"liar: dropped from the image ({what}" in log, f"the liar was not dropped for {what!r}:\n{log[-3000:]}")
    status = read_status(run.status)
    check(status.get("image_tiles") == 6 and status.get("image_tiles_done") == 6, f"the image's tiles: {status}")
    check(sum(n.get("tiles", 0) for n in status["nodes"]) == 6, f"not every tile from a node once: {status}")
    one = Proc([os.path.join(build, "sirad"), "image", run.out + ".ply", "--spp", "4", "--width", "96", "--height", "64",
                "--out", os.path.join(work, "one"), "-q"], os.path.join(work, "one.log"))
    check(one.wait() == 0, f"sirad image: {one.log()}")
    with open(run.out + ".png", "rb") as a, open(os.path.join(work, "one.png"), "rb") as b:
        check(a.read() == b.read(), "the run's image is not the image of its solution")


def case_pixels_not_finite(build, work, ctx):
    """Class 18: a PIXELS whose first tile holds a NaN."""
    def lie(frames):
        tile = bytearray(frames[3])
        tile[0:4] = struct.pack("<f", float("nan"))
        return frames[:3] + [bytes(tile)] + frames[4:]
    lying_pixels_case(build, work, ctx, lie, "a tile's pixel 0 is not finite")


def case_pixels_other_tiles(build, work, ctx):
    """Class 18: a PIXELS that names other tiles than its grant's (the next tile's index)."""
    def lie(frames):
        px = pb.Pixels.FromString(frames[2])
        for r in px.done:
            r.first += 1
            r.last += 1
        return frames[:2] + [px.SerializeToString()] + frames[3:]
    lying_pixels_case(build, work, ctx, lie, "PIXELS for grant")


def case_pixels_withheld(build, work, ctx):
    """Class 18: a node that renders its tiles but never sends them (each PIXELS replaced by a
    HEARTBEAT, so it looks alive): once the honest node has sent tiles, the liar's first grant is
    due 16 times the honest time per tile (plus the slack), not the 30 s and more a first grant
    may take; it is dropped as overdue and its tiles are granted again."""
    pixels_cmd = CMD["pixels"]

    def withhold(frames):
        if len(frames) < 3 or frames[0] != SIG or frames[1][0] != pixels_cmd:
            return None
        return [SIG, bytes([CMD["heartbeat"]]) + frames[1][1:], b""]

    run = Run(build, work, 1024, 2, ["--final-gather", "4"], size=(96, 64))
    proxy = run_with_liar(run, ctx, withhold, 1)
    log = run.check_result({"h0", "liar"})
    check(proxy.lied >= 1, "the liar withheld no PIXELS (it was granted no tiles?)")
    check("image: first tiles now due within" in log, f"the first grants were not brought forward:\n{log[-3000:]}")
    check("liar: dropped from the image (grant" in log and "overdue" in log, f"the liar was not dropped as overdue:\n{log[-3000:]}")
    status = read_status(run.status)
    check(status.get("image_tiles_done") == 6, f"the image's tiles: {status}")
    honest = [n for n in status["nodes"] if n["name"] == "h0"]
    check(honest and honest[0].get("tiles") == 6, f"the honest node did not render every tile: {status['nodes']}")


def case_image_time_limit(build, work, ctx):
    """Issue 35: the run's time limit reached during the image (its only node withholds every
    PIXELS, as pixels_withheld's liar). The limit, 35 s, is past what the node's set-up and the
    solve of 256 bundles take even on a loaded machine (seconds), and before the liar's first
    tiles are due, 40 s after the image began (a first grant's 30 s and the 10 s slack: then it
    would be dropped and the coordinator would render the tiles it never held). The image fails, not the run: the
    solution is kept (NAME.ply, NAME.glb, the ledger), no image is written, the exit status is
    1 and the error names the limit and the tiles done."""
    pixels_cmd = CMD["pixels"]

    def withhold(frames):
        if len(frames) < 3 or frames[0] != SIG or frames[1][0] != pixels_cmd:
            return None
        return [SIG, bytes([CMD["heartbeat"]]) + frames[1][1:], b""]

    run = Run(build, work, 256, 1, ["--final-gather", "4"], size=(96, 64), timeout=35)
    proxy = run_with_liar(run, ctx, withhold, 0)
    log = run.coordinator.log()
    check(run.coordinator.rc == 1, f"coordinator exit {run.coordinator.rc}, not 1:\n{log[-4000:]}")
    check(proxy.lied >= 1, "the liar withheld no PIXELS (it was granted no tiles?)")
    check("the run's time limit of 35 s was reached with 0 of 6 tiles done" in log, f"the image did not fail at the limit:\n{log[-4000:]}")
    check("the solution is kept in" in log, f"the error does not say the solution was kept:\n{log[-4000:]}")
    for ext in (".exr", ".png"):
        check(not os.path.exists(run.out + ext), f"{run.out + ext} was written without an image")
    check(os.path.getsize(run.out + ".ply") > 0 and os.path.getsize(run.out + ".glb") > 0, "the solution was not kept")
    rows = ledger_ranges(run.ledger)
    check(sum(last - first for _, _, first, last in rows) == 256, f"the ledger does not hold the 256 bundles: {rows}")


def case_pixels_wrong(build, work, ctx):
    """Class 18: a PIXELS of finite pixels that are not the image's (every value of its first tile
    1.5 times what the node rendered): the coordinator's spot check of two of the tile's pixels,
    rendered there, refuses it."""
    def lie(frames):
        n = len(frames[3]) // 4
        values = struct.unpack(f"<{n}f", frames[3])
        return frames[:3] + [struct.pack(f"<{n}f", *(1.5 * v for v in values))] + frames[4:]
    lying_pixels_case(build, work, ctx, lie, "pixel (")


def case_poison_bundles(build, work, ctx):
    """Class 2, bundles that crash every node they go to (issue 35): three nodes in turn (from
    three addresses) each join, take their grants (the lowest free bundles: the ones the node
    before died with) and die. At the third loss the run is not handed to a fourth node: it
    closes, names the bundles in the log and in status.json's ended_by, and ends with the
    bundles done (none here), its outputs written, and exit status 1: not the run asked for."""
    run = Run(build, work, 1024, 1)
    port = run.endpoint.rsplit(":", 1)[1]
    for i in range(3):  # from three addresses: one peer that keeps coming back counts once
        p = Peer(ctx, f"tcp://127.0.0.{10 + i}:0;127.0.0.1:{port}", f"crash{i}")
        p.join([run.coordinator])
        p.wait_grant(run.coordinator)
        p.s.close(linger=0)  # dies with its grants
        wait_until(f"crash{i} declared dead", lambda: f"crash{i}: declared dead" in run.coordinator.log(), [run.coordinator])
    rc = run.finish()
    log = run.coordinator.log()
    check(rc == 1, f"coordinator exit {rc}, not 1:\n{log[-4000:]}")
    check("bundles 0.." in log and "were lost with 3 nodes" in log, f"the run did not name the lost bundles:\n{log[-4000:]}")
    status = read_status(run.status)
    check("were lost with 3 nodes" in (status.get("ended_by") or ""), f"status.json's ended_by: {status.get('ended_by')}")
    check(os.path.exists(run.out + ".ply"), "no outputs")


class CrashingProxy(LyingProxy):
    """A real sirad-node that "crashes" on the image's first TILES it is granted: from that message
    on, the proxy passes nothing either way, as if the node had died rendering the tile."""

    def __init__(self, ctx, coordinator_endpoint):
        super().__init__(ctx, coordinator_endpoint, lambda frames: None)

    def heard(self, frames):
        if len(frames) >= 2 and frames[0] == SIG and frames[1][0] == CMD["tiles"]:
            self.crashed = True


def case_poison_tile(build, work, ctx):
    """Class 18, a tile that crashes every node it goes to (issue 35): three nodes, each gone at
    its first TILES, on an image of one tile. The tile is lost with all three
    (TilePlan::kMaxTileLosses), and is never rendered by the coordinator itself; the image
    fails with its reason, and the solution the run made before it is kept: the coordinator
    exits 1 naming the image's failure and the files kept, and furnace.ply (the furnace's right
    answer) and furnace.glb are written, no EXR or PNG."""
    run = Run(build, work, 1024, 3, ["--final-gather", "4"], size=(32, 32))
    proxies = [CrashingProxy(ctx, run.endpoint) for _ in range(3)]
    nodes = [Proc([os.path.join(build, "sirad-node"), "--connect", p.endpoint, "--name", f"crash{i}", "--insecure"],
                  os.path.join(work, f"crash{i}.log")) for i, p in enumerate(proxies)]
    try:
        rc = run.finish()
    finally:
        for n in nodes:
            n.stop()
        for p in proxies:
            p.stop()
    log = run.coordinator.log()
    check(rc == 1, f"coordinator exit {rc}, not 1:\n{log[-4000:]}")
    check(sum(p.crashed for p in proxies) == 3, f"{sum(p.crashed for p in proxies)} of 3 nodes were granted the tile")
    check("tile 0 was lost with 3 nodes" in log, f"the image did not fail for its tile:\n{log[-4000:]}")
    check("no image (" in log and "the solution is kept in" in log, f"the error does not say the solution was kept:\n{log[-4000:]}")
    check("renders the" not in log or "never rendered here" in log, f"the coordinator rendered the lost tile:\n{log[-4000:]}")
    for ext in (".exr", ".png"):
        check(not os.path.exists(run.out + ext), f"{run.out + ext} was written without an image")
    check(os.path.getsize(run.out + ".glb") > 0, "no glb")
    check(len(ledger_ranges(run.ledger)) > 0, "no ledger")
    radiosity = ply_radiosity(run.out + ".ply")
    mean = sum(r for r, _, _ in radiosity) / len(radiosity)
    tol = 0.0097 * 4  # as Run.check_result: 4 sd of a 1024-bundle chain average's mean
    check(abs(mean - 2.0) <= tol, f"the kept solution's furnace mean {mean} is not 2 within {tol}")


# --- the farm -------------------------------------------------------------------------------

class Farm:
    """A farm (sirad-coordinator --serve) in WORK/farm over loopback: its ZeroMQ endpoint, HTTP
    address and token. Nodes heartbeat every 200 ms and are forgotten after 25 silent beats."""

    def __init__(self, build, work):
        self.build, self.work = build, work
        self.folder = os.path.join(work, "farm")
        endpoint_file = os.path.join(work, "farm-endpoint")
        self.proc = Proc([os.path.join(build, "sirad-coordinator"), "--serve", self.folder, "--listen", "tcp://127.0.0.1:*",
                          "--insecure", "--endpoint-file", endpoint_file, "--http", "127.0.0.1:0", "--heartbeat-ms", "200",
                          "--liveness", "25", "--checkpoint-every", "0.2"], os.path.join(work, "farm.log"))
        http_file = os.path.join(self.folder, "http")
        wait_until("the farm's addresses", lambda: all(os.path.exists(f) and os.path.getsize(f) > 0 for f in (endpoint_file, http_file)),
                   [self.proc])
        with open(endpoint_file) as f:
            self.endpoint = f.read().strip()
        with open(http_file) as f:
            self.host, port = f.read().strip().split("//")[1].split(":")
            self.port = int(port)
        with open(os.path.join(self.folder, "token")) as f:
            self.token = f.read().strip()

    def raw(self, request):
        """Sends `request` (bytes) on a new connection; what the farm answers until it closes it."""
        import socket
        with socket.create_connection((self.host, self.port), timeout=CAP_S) as c:
            c.sendall(request)
            got = b""
            while True:
                d = c.recv(65536)
                if not d:
                    return got
                got += d

    def get(self, path):
        """GET `path`: (status code, body)."""
        answer = self.raw(f"GET {path} HTTP/1.1\r\nHost: farm\r\nConnection: close\r\n\r\n".encode())
        head, _, body = answer.partition(b"\r\n\r\n")
        return int(head.split(b" ")[1]), body

    def job(self, id):
        import json
        code, body = self.get(f"/api/jobs/{id}")
        check(code == 200, f"GET /api/jobs/{id}: {code} {body[:300]}")
        return json.loads(body)

    def submit(self, args):
        sub = Proc([os.path.join(self.build, "sirad"), "submit"] + args + ["--farm", self.folder], os.path.join(self.work, "submit.log"))
        check(sub.wait() == 0, f"sirad submit: {sub.log()}")

    def stop(self):
        """SIGTERM: the farm checkpoints its running jobs and exits 0."""
        self.proc.p.send_signal(signal.SIGTERM)
        check(self.proc.wait() == 0, f"the farm exited {self.proc.rc}:\n{self.proc.log()[-3000:]}")


def case_farm_hostile_requests(build, work, ctx):
    """HTTP requests a browser never sends, each answered with its 4xx at once (no crash, no hang,
    no file outside a job's outputs): paths out of a job's folder (plain and %-encoded), the token
    by name, an id past 64 bits, a URI of 100 KB and a head of 2,000 fields (the guard's 16 KiB
    head: 431), a NUL in the path, an unknown method, a request without a version, a body of
    93 GiB claimed (413 before any of it is read) or a chunk of 2^64 - 1 bytes, paging numbers
    that are negative, past 64 bits or not numbers, a cancel without the token, and a job nested
    200,000 levels deep (refused by the JSON reader's 64 levels). No answer carries the token;
    after them the page and the API answer, and the farm's peak memory stays under 200 MiB (it
    is about 30 MiB idle)."""
    farm = Farm(build, work)
    auth = f"Authorization: Bearer {farm.token}\r\n".encode()
    deep = b'{"name": "deep", "scene": "cornell", "priority": 0, "args": [], "x": ' + b"[" * 200000 + b"]" * 200000 + b"}"
    form = (b"--b\r\nContent-Disposition: form-data; name=\"job\"\r\n\r\n" + deep + b"\r\n--b--\r\n")
    close = b"Connection: close\r\n"
    cases = [
        (b"GET /api/jobs/1/files/../../token HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 404),
        (b"GET /api/jobs/1/files/..%2f..%2ftoken HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 404),
        (b"GET /token HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 404),
        (b"GET /api/jobs/999999999999999999999999999999 HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 404),
        (b"GET /" + b"a" * 100000 + b" HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 431),
        (b"GET / HTTP/1.1\r\n" + b"".join(b"X-%d: y\r\n" % i for i in range(2000)) + close + b"\r\n", 431),
        (b"GET /\x00 HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 400),
        (b"FOO /api/jobs HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 400),
        (b"GET /\r\n\r\n", 400),
        (b"POST /api/jobs HTTP/1.1\r\nHost: f\r\n" + auth + b"Content-Length: 99999999999\r\n" + close + b"\r\nabc", 413),
        (b"POST /api/jobs HTTP/1.1\r\nHost: f\r\n" + auth + b"Transfer-Encoding: chunked\r\n" + close + b"\r\nffffffffffffffff\r\nabc\r\n",
         400),
        (b"GET /api/jobs?limit=-1&before=-5 HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 400),
        (b"GET /api/jobs?limit=99999999999999999999999&before=abc HTTP/1.1\r\nHost: f\r\n" + close + b"\r\n", 400),
        (b"POST /api/jobs/1/cancel HTTP/1.1\r\nHost: f\r\nContent-Length: 0\r\n" + close + b"\r\n", 401),
        (b"POST /api/jobs HTTP/1.1\r\nHost: f\r\n" + auth + b"Content-Type: multipart/form-data; boundary=b\r\n" +
         f"Content-Length: {len(form)}\r\n".encode() + close + b"\r\n" + form, 400),
    ]
    for request, want in cases:
        answer = farm.raw(request)
        status = answer.split(b"\r\n", 1)[0]
        check(status.startswith(b"HTTP/1.1 %d" % want), f"{request[:80]!r}...: {status!r}, not {want}")
        check(farm.token.encode() not in answer, f"{request[:80]!r}...: the answer carries the token")
        check(farm.proc.poll() is None, f"the farm exited after {request[:80]!r}:\n{farm.proc.log()[-3000:]}")
    check(b"nested deeper than 64 levels" in farm.raw(cases[-1][0]), "the deep job was not refused for its depth")
    for path in ("/", "/api/jobs"):
        code, body = farm.get(path)
        check(code == 200, f"GET {path} after the requests: {code} {body[:200]}")
    farm.stop()
    print(f"farm peak {farm.proc.maxrss_kib / 1024:.0f} MiB")
    check(farm.proc.maxrss_kib < 200 * 1024, f"the farm peaked at {farm.proc.maxrss_kib / 1024:.0f} MiB")


def case_farm_poison_bundles(build, work, ctx):
    """A farm job whose bundles crash every node they go to (issue 35: a node that crashes on a
    job is not handed the same work forever): three nodes in turn (from three addresses) join
    it, take their grants and die. The job fails at the third loss, naming the bundles, with its outputs kept; the farm
    stays up, and the next job runs to its end on an honest node."""
    farm = Farm(build, work)
    farm.submit(["furnace", "--name", "poison", "--patches", "300", "--bundles", "1024", "--width", "16", "--height", "16"])
    port = farm.endpoint.rsplit(":", 1)[1]
    for i in range(3):  # from three addresses
        p = Peer(ctx, f"tcp://127.0.0.{10 + i}:0;127.0.0.1:{port}", f"crash{i}")
        p.join([farm.proc])
        p.wait_grant(farm.proc)
        p.s.close(linger=0)  # dies with its grants
        if i < 2:
            wait_until(f"crash{i} declared dead", lambda: f"crash{i}: declared dead" in farm.proc.log(), [farm.proc])
    wait_until("the poisoned job's end", lambda: farm.job(1)["state"] in ("done", "failed"), [farm.proc])
    job = farm.job(1)
    check(job["state"] == "failed" and "were lost with 3 nodes" in job["error"], f"job 1: {job}")
    check(os.path.exists(os.path.join(farm.folder, "jobs", "1", "poison.ply")), "the poisoned job's outputs were not kept")
    farm.submit(["furnace", "--name", "next", "--patches", "300", "--bundles", "256", "--width", "16", "--height", "16"])
    node = Proc([os.path.join(build, "sirad-node"), "--connect", farm.endpoint, "--name", "honest", "--insecure"],
                os.path.join(work, "honest.log"))
    wait_until("the next job's end", lambda: farm.job(2)["state"] in ("done", "failed"), [farm.proc])
    check(farm.job(2)["state"] == "done", f"job 2: {farm.job(2)}")
    node.stop()
    farm.stop()


CASES = {name[len("case_"):]: fn for name, fn in globals().items() if name.startswith("case_")}


def main():
    global pb
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ap.add_argument("--case")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--keep", action="store_true", help="keep the work directory")
    a = ap.parse_args()
    if a.list:
        print("\n".join(CASES))
        return 0
    sys.path.insert(0, os.path.join(a.build, "python"))
    import sirad_pb2
    pb = sirad_pb2
    work = tempfile.mkdtemp(prefix=f"sirad_hostile_{a.case}_")
    ctx = zmq.Context()
    try:
        CASES[a.case](os.path.abspath(a.build), work, ctx)
    except Failure as e:
        print(f"FAILED {a.case}: {e}\n(work directory kept: {work})")
        return 1
    finally:
        Proc.kill_all()
        ctx.destroy(linger=0)
    print(f"passed {a.case}")
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
