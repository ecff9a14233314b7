"""ur-rtde's own RTDEReceiveInterface (the real wheel) against the loopback controller: the
protocol as the client speaks it, the rate it picks from the controller's version, the values it
reads back, and the backends' reads through it."""

from __future__ import annotations

import time

import numpy as np
import pytest
import rtde_receive  # the real ur-rtde wheel (requirements/robot.txt): missing, the tests fail

from mimicrete.robot.rtde import OUTPUTS, RtdeReader, ShadowRobot

from ._rtde_server import LoopbackRobot


@pytest.mark.parametrize(("version", "rate"), [((3, 15, 7, 0), 125.0), ((5, 21, 0, 0), 500.0)])
def test_the_real_client_negotiates_and_reads(version, rate):
    q = [0.1, -0.2, 0.3, -0.4, 0.5, -0.6]
    tcp = [0.2, 0.3, 0.4, 3.1, 0.0, 0.1]
    with LoopbackRobot(q, tcp=tcp, version=version, digital_out=0b101, digital_in=0b10) as c:
        r = rtde_receive.RTDEReceiveInterface(c.host, -1.0, OUTPUTS)
        time.sleep(0.1)
        assert r.isConnected()
        assert r.getActualQ() == pytest.approx(q)
        assert r.getActualTCPPose() == pytest.approx(tcp)
        assert r.getSafetyMode() == 1
        assert r.getActualDigitalOutputBits() == 0b101
        assert r.getActualDigitalInputBits() == 0b10
        t1 = r.getTimestamp()
        time.sleep(0.05)
        assert r.getTimestamp() > t1  # the stream keeps coming
        r.disconnect()
        r.reconnect()  # ur-rtde 1.6.5 sends no pause (P) on disconnect: it just closes
        time.sleep(0.05)
        assert r.isConnected()
        log = c.log()
        r.disconnect()
    kinds = [e[0] for e in log["log"]]
    # V (protocol 2), v, O (the explicit recipe, ending with an empty name), S; again on reconnect
    assert kinds == ["V", "v", "O", "S"] * 2, log
    assert log["log"][0] == ["V", 2]
    _, freq, names = log["log"][2]
    assert freq == rate  # 500 Hz of an e-Series, 125 Hz of a CB3: from the version reply
    assert names == [*OUTPUTS, ""]
    assert "I" not in kinds  # a receive client sets up no inputs: it cannot command anything
    assert log["errors"] == []
    assert log["packages"] > 0.04 * rate  # streamed at about the asked rate for >= 0.15 s


def test_pause_and_a_bad_protocol_version_by_hand():
    """What ur-rtde's receive interface never sends: a pause, a protocol version the server
    refuses (the server answers as a controller would)."""
    import socket
    import struct

    def ask(sock, kind, payload=b""):
        sock.sendall(struct.pack(">HB", 3 + len(payload), ord(kind)) + payload)
        size, k = struct.unpack(">HB", sock.recv(3))
        body = b""
        while len(body) < size - 3:
            body += sock.recv(size - 3 - len(body))
        assert chr(k) == kind
        return body

    with LoopbackRobot([0.0] * 6) as c, socket.create_connection((c.host, 30004)) as sock:
        assert ask(sock, "V", struct.pack(">H", 3)) == b"\x00"  # only version 2 is spoken
        assert ask(sock, "V", struct.pack(">H", 2)) == b"\x01"
        reply = ask(sock, "O", struct.pack(">d", 125.0) + b"actual_q,no_such_output,")
        assert reply[1:] == b"VECTOR6D,NOT_FOUND"
        assert ask(sock, "S") == b"\x00"  # a recipe naming an unknown output does not start
        ask(sock, "O", struct.pack(">d", 125.0) + b"actual_q,")
        assert ask(sock, "S") == b"\x01"
        size, k = struct.unpack(">HB", sock.recv(3))
        assert chr(k) == "U" and size == 3 + 1 + 48
        sock.recv(size - 3)
        sock.sendall(struct.pack(">HB", 3, ord("P")))
        # data packages already on the way may come first; then the pause's reply
        for _ in range(100):
            size, k = struct.unpack(">HB", sock.recv(3))
            body = sock.recv(size - 3)
            if chr(k) == "P":
                assert body == b"\x01"
                break
        else:
            raise AssertionError("no reply to the pause")


def test_shadow_backend_reads_a_protective_stop_and_sends_nothing():
    q = [0.0, -1.5, 1.5, -1.5, -1.5, 0.0]
    with LoopbackRobot(q) as c:
        robot = ShadowRobot(c.host)
        time.sleep(0.05)
        s = robot.read()
        assert s.connected and s.safety_mode == 1
        assert np.allclose(s.q, q)
        robot.send_joint_target(np.asarray(q) + 0.01, True)
        c.set(safety_mode=3)
        time.sleep(0.05)
        assert robot.read().safety_mode == 3
        robot.stop("test")
        robot.close()
        kinds = [e[0] for e in c.log()["log"]]
    assert robot.would_send is not None  # computed ...
    assert kinds.count("S") == 1 and "I" not in kinds  # ... and never sent (no input recipe)


def test_reader_sees_a_dropped_socket():
    with LoopbackRobot([0.0] * 6) as c:
        reader = RtdeReader(c.host)
        time.sleep(0.05)
        assert reader.read().connected
        c.drop()
        deadline = time.monotonic() + 2.0
        while reader.read().connected and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not reader.read().connected
        reader.close()
