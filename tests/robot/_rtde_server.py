"""A loopback RTDE server (Universal Robots' Real-Time Data Exchange, protocol version 2) that the
real ur-rtde client connects to in the tests: written from UR's protocol description, serving
only what a receive client asks for.

Every package: a big-endian header (uint16 size including the header, uint8 type), then the
payload. Types: ``V`` protocol version (client: uint16 version; reply: uint8 accepted), ``v``
controller version (reply: uint32 major, minor, bugfix, build), ``O`` output recipe setup
(client: double frequency + comma-separated names; reply: uint8 recipe id + comma-separated
types), ``I`` input recipe setup (reply: recipe id + types), ``S`` start / ``P`` pause (reply:
uint8 accepted), ``U`` data package (uint8 recipe id + the recipe's values in order), ``M`` text
message.

ur-rtde's receive interface connects to port 30004 of its host (the port is fixed), so each
server binds port 30004 on a loopback address of its own (127.x.y.z: Linux routes all of
127.0.0.0/8 to lo) that it finds free; tests running at once do not collide.

The server runs in a process of its own (``python _rtde_server.py``; :class:`LoopbackRobot` starts
and scripts it over stdin/stdout, one JSON object a line): ur-rtde's constructor holds Python's
interpreter lock while it connects, so a server thread in the test's own process could not answer.

The robot's state is scripted by the test (:class:`RobotScript`): joint angles, TCP pose, safety
mode, digital outputs; faults are injected by changing it (a protective stop: safety mode 3; a
joint jump; ``stall`` stops the data packages without closing; ``drop`` closes the socket).
"""

from __future__ import annotations

import random
import socket
import struct
import threading
import time
from dataclasses import dataclass, field

RTDE_PORT = 30004
HEADER = struct.Struct(">HB")

#: the outputs this server can serve: name -> (RTDE type, struct format of its value)
OUTPUTS: dict[str, tuple[str, str]] = {
    "timestamp": ("DOUBLE", "d"),
    "actual_q": ("VECTOR6D", "6d"),
    "target_q": ("VECTOR6D", "6d"),
    "actual_TCP_pose": ("VECTOR6D", "6d"),
    "safety_mode": ("INT32", "i"),
    "robot_mode": ("INT32", "i"),
    "runtime_state": ("UINT32", "I"),
    "safety_status_bits": ("UINT32", "I"),
    "robot_status_bits": ("UINT32", "I"),
    "actual_digital_output_bits": ("UINT64", "Q"),
    "actual_digital_input_bits": ("UINT64", "Q"),
    "speed_scaling": ("DOUBLE", "d"),
}


@dataclass
class RobotScript:
    """The state the server streams; tests change it while the server runs (under ``lock``)."""

    q: list[float]
    tcp: list[float] = field(default_factory=lambda: [0.0] * 6)
    safety_mode: int = 1
    robot_mode: int = 7  # RUNNING
    digital_out: int = 0
    digital_in: int = 0
    stall: bool = False
    lock: threading.Lock = field(default_factory=threading.Lock)

    def value(self, name: str, t: float):
        if name == "timestamp":
            return (t,)
        if name in ("actual_q", "target_q"):
            return tuple(float(x) for x in self.q)
        if name == "actual_TCP_pose":
            return tuple(float(x) for x in self.tcp)
        if name == "safety_mode":
            return (self.safety_mode,)
        if name == "robot_mode":
            return (self.robot_mode,)
        if name == "runtime_state":
            return (2,)  # PLAYING
        if name == "safety_status_bits":
            # bit 0 normal, bit 2 protective stopped
            return (
                (1 << 0) if self.safety_mode == 1 else (1 << 2) if self.safety_mode == 3 else 0,
            )
        if name == "robot_status_bits":
            return (0b1111,)
        if name == "actual_digital_output_bits":
            return (self.digital_out,)
        if name == "actual_digital_input_bits":
            return (self.digital_in,)
        if name == "speed_scaling":
            return (1.0,)
        raise KeyError(name)


class ProtocolError(Exception):
    pass


def _free_loopback_host() -> tuple[socket.socket, str]:
    """A listening socket on port 30004 of a free 127.x.y.z address."""
    rng = random.Random()
    last: OSError | None = None
    for _ in range(200):
        host = f"127.{rng.randint(1, 254)}.{rng.randint(0, 255)}.{rng.randint(1, 254)}"
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            s.bind((host, RTDE_PORT))
        except OSError as e:
            s.close()
            last = e
            continue
        s.listen(4)
        return s, host
    raise OSError(f"no free loopback address for port {RTDE_PORT}: {last}")


class RtdeServer:
    """One scripted controller. ``version``: the controller version it reports (major 3: CB3,
    whose client streams at 125 Hz; 5: e-Series, 500 Hz). ``log`` records what the client sent:
    ``("V", version)``, ``("v",)``, ``("O", frequency, names)``, ``("I", names)``, ``("S",)``,
    ``("P",)``; ``packages`` counts the data packages sent."""

    def __init__(self, script: RobotScript, version: tuple[int, int, int, int] = (3, 15, 7, 0)):
        self.script = script
        self.version = version
        self.sock, self.host = _free_loopback_host()
        self.log: list[tuple] = []
        self.errors: list[str] = []
        self.packages = 0
        self.frequency: float | None = None
        self.recipe: list[str] = []
        self._conns: list[socket.socket] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._accept, daemon=True, name="rtde-server")
        self._thread.start()
        self.t0 = time.monotonic()

    # --- the tests' handles --------------------------------------------------------------------

    def drop(self) -> None:
        """Close every client socket (a cable pulled, the controller restarted)."""
        for c in list(self._conns):
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            c.close()
        self._conns.clear()

    def close(self) -> None:
        self._stop.set()
        self.drop()
        self.sock.close()
        self._thread.join(timeout=2)

    def __enter__(self) -> RtdeServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def wait_started(self, timeout: float = 5.0) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if any(e[0] == "S" for e in self.log):
                return
            time.sleep(0.005)
        raise TimeoutError(f"no client started a stream; log {self.log}, errors {self.errors}")

    # --- the protocol ---------------------------------------------------------------------------

    def _accept(self) -> None:
        self.sock.settimeout(0.1)
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._conns.append(conn)
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _send(self, conn: socket.socket, kind: str, payload: bytes) -> None:
        conn.sendall(HEADER.pack(HEADER.size + len(payload), ord(kind)) + payload)

    def _recv_exact(self, conn: socket.socket, n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            chunk = conn.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("client closed")
            buf += chunk
        return buf

    def _serve(self, conn: socket.socket) -> None:
        streamer: threading.Thread | None = None
        streaming = threading.Event()
        try:
            while not self._stop.is_set():
                size, kind = HEADER.unpack(self._recv_exact(conn, HEADER.size))
                if size < HEADER.size:
                    raise ProtocolError(f"package size {size} below the header's")
                payload = self._recv_exact(conn, size - HEADER.size)
                k = chr(kind)
                if k == "V":
                    (version,) = struct.unpack(">H", payload)
                    self.log.append(("V", version))
                    self._send(conn, "V", struct.pack(">B", 1 if version == 2 else 0))
                elif k == "v":
                    self.log.append(("v",))
                    self._send(conn, "v", struct.pack(">IIII", *self.version))
                elif k == "O":
                    (freq,) = struct.unpack(">d", payload[:8])
                    names = payload[8:].decode("ascii").split(",")
                    self.log.append(("O", freq, names))
                    wanted = [n for n in names if n]  # the client's list ends with an empty name
                    types = [OUTPUTS[n][0] if n in OUTPUTS else "NOT_FOUND" for n in wanted]
                    self.frequency, self.recipe = freq, wanted
                    self._send(conn, "O", struct.pack(">B", 1) + ",".join(types).encode())
                elif k == "I":
                    names = payload.decode("ascii").split(",")
                    self.log.append(("I", names))
                    types = ["NOT_FOUND" for n in names if n]
                    self._send(conn, "I", struct.pack(">B", 0) + ",".join(types).encode())
                elif k == "S":
                    self.log.append(("S",))
                    ok = bool(self.recipe) and all(n in OUTPUTS for n in self.recipe)
                    self._send(conn, "S", struct.pack(">B", 1 if ok else 0))
                    if ok and streamer is None:
                        streaming.set()
                        streamer = threading.Thread(
                            target=self._stream, args=(conn, streaming), daemon=True
                        )
                        streamer.start()
                elif k == "P":
                    self.log.append(("P",))
                    streaming.clear()
                    self._send(conn, "P", struct.pack(">B", 1))
                else:
                    self.log.append((k, payload))
        except (ConnectionError, OSError):
            pass
        except ProtocolError as e:
            self.errors.append(str(e))
        finally:
            streaming.clear()
            try:
                conn.close()
            except OSError:
                pass

    def _stream(self, conn: socket.socket, streaming: threading.Event) -> None:
        period = 1.0 / (self.frequency or 125.0)
        fmt = ">B" + "".join(OUTPUTS[n][1] for n in self.recipe)
        next_t = time.monotonic()
        while streaming.is_set() and not self._stop.is_set():
            with self.script.lock:
                stalled = self.script.stall
                if not stalled:
                    t = time.monotonic() - self.t0
                    values: list = [1]
                    for n in self.recipe:
                        values.extend(self.script.value(n, t))
                    data = struct.pack(fmt, *values)
            if not stalled:
                try:
                    self._send(conn, "U", data)
                except OSError:
                    return
                self.packages += 1
            next_t += period
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_t = time.monotonic()


# --- the server process and its handle in the test ------------------------------------------------


def _serve_stdio() -> None:
    """The server process: reads commands (JSON lines) on stdin, answers on stdout."""
    import json
    import sys

    first = json.loads(sys.stdin.readline())
    script = RobotScript(q=list(first["q"]), tcp=list(first.get("tcp", [0.0] * 6)))
    for k, v in first.get("set", {}).items():
        setattr(script, k, v)
    server = RtdeServer(script, tuple(first.get("version", (3, 15, 7, 0))))
    print(json.dumps({"host": server.host}), flush=True)
    for line in sys.stdin:
        cmd = json.loads(line)
        if "set" in cmd:
            with script.lock:
                for k, v in cmd["set"].items():
                    setattr(script, k, v)
            reply = {"ok": True}
        elif "drop" in cmd:
            server.drop()
            reply = {"ok": True}
        elif "log" in cmd:
            reply = {
                "log": server.log,
                "errors": server.errors,
                "packages": server.packages,
                "frequency": server.frequency,
            }
        else:
            break
        print(json.dumps(reply), flush=True)
    server.close()


class LoopbackRobot:
    """A scripted controller in a child process (see the module's doc): ``host`` to connect to;
    ``set(**fields)`` changes what it streams (``q``, ``tcp``, ``safety_mode``, ``digital_out``,
    ``stall``), ``drop()`` closes the client's socket, ``log()`` what the client sent."""

    def __init__(self, q, tcp=None, version=(3, 15, 7, 0), **fields) -> None:
        import json
        import subprocess
        import sys

        self._json = json
        self.proc = subprocess.Popen(
            [sys.executable, __file__],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        first = {"q": [float(x) for x in q], "version": list(version), "set": fields}
        if tcp is not None:
            first["tcp"] = [float(x) for x in tcp]
        self.host = self._ask(first)["host"]

    def _ask(self, cmd: dict) -> dict:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(self._json.dumps(cmd) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the loopback RTDE server exited ({self.proc.poll()})")
        return self._json.loads(line)

    def set(self, **fields) -> None:
        conv = {k: ([float(x) for x in v] if k in ("q", "tcp") else v) for k, v in fields.items()}
        self._ask({"set": conv})

    def drop(self) -> None:
        self._ask({"drop": True})

    def log(self) -> dict:
        return self._ask({"log": True})

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write('{"quit": true}\n')
                self.proc.stdin.close()
                self.proc.wait(timeout=5)
            except (OSError, ValueError, TimeoutError):
                self.proc.kill()
                self.proc.wait()

    def __enter__(self) -> LoopbackRobot:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


if __name__ == "__main__":
    _serve_stdio()
