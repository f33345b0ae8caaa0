"""Limits on the socketcand front end: 100 clients of which 10 never read
while a 1 ms heartbeat streams to them all; a client that floods the bus with frames. The SDO
round trips of a client that behaves stay as they were within noise, the clients that never
read are dropped after their bounded queue, the flood cannot starve the others, and the twin
logs each of these once, not per frame.
"""

from __future__ import annotations

import selectors
import socket
import statistics
import threading
import time

from conftest import CHANNEL, HOST, wait_until


def handshake(port: int) -> socket.socket:
    s = socket.create_connection((HOST, port), timeout=5)
    buf = b""

    def expect(text: bytes):
        nonlocal buf
        deadline = time.monotonic() + 5
        while text not in buf:
            assert time.monotonic() < deadline, (text, buf)
            buf += s.recv(4096)
        buf = buf[buf.index(text) + len(text):]

    expect(b"< hi >")
    s.sendall(f"< open {CHANNEL} >".encode())
    expect(b"< ok >")
    s.sendall(b"< rawmode >")
    expect(b"< ok >")
    return s


def sdo_round_trips(port: int, count: int) -> list[float]:
    """Expedited SDO uploads of 1018h:01 from node 1, seconds each."""
    s = handshake(port)
    s.settimeout(2)
    times = []
    buf = b""
    try:
        for _ in range(count):
            t0 = time.perf_counter()
            s.sendall(b"< send 601 8 40 18 10 01 00 00 00 00 >")
            # Other clients' frames stream in as well: keep only a tail to search.
            while b"< frame 581 " not in buf:
                chunk = s.recv(65536)
                assert chunk, "the twin closed the connection"
                buf = buf[-64:] + chunk
            times.append(time.perf_counter() - t0)
            buf = b""
    finally:
        s.close()
    return times


def cell_file(tmp_path, heartbeat_ms: int):
    # The instant bus: these are tests of the socketcand front end under floods at what a
    # 1 Mbit/s bus carries. On the default cell's 125 kbit/s bus the flood's 321h frames would
    # win every arbitration against the SDO request 601h, which then waits as on a real bus.
    cell = tmp_path / "limits.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "max_clients = 128",
        'bitrate = "instant"', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 1", "[drive.objects]", f'"1017:00" = {heartbeat_ms}', "",
    ]))
    return cell


def test_100_clients_of_which_10_never_read(launch, tmp_path):
    """100 clients on one server while another puts 5000 frames/s on the bus: the SDO round
    trips of a client that behaves are the same with 10 of the others never reading as with
    all of them reading; each silent client is dropped after its bounded queue, logged once."""
    twin = launch(config=cell_file(tmp_path, 1000))
    port = twin.port
    readers = [handshake(port) for _ in range(89)]
    stop = threading.Event()
    sel = selectors.DefaultSelector()
    for r in readers:
        r.setblocking(False)
        sel.register(r, selectors.EVENT_READ)

    def drain():
        while not stop.is_set():
            for key, _ in sel.select(0.05):
                try:
                    key.fileobj.recv(1 << 16)
                except (BlockingIOError, ConnectionError):
                    pass

    # A quarter of what 1 Mbit/s carries, so a silent client's queue fills in seconds.
    producer = handshake(port)

    def produce():
        frame = b"< send 321 8 01 02 03 04 05 06 07 08 >" * 5
        while not stop.is_set():
            producer.sendall(frame)
            time.sleep(0.001)

    threads = [threading.Thread(target=f, daemon=True) for f in (drain, produce)]
    for t in threads:
        t.start()
    silent = []
    try:
        time.sleep(0.5)
        all_reading = sdo_round_trips(port, 300)
        silent = [handshake(port) for _ in range(10)]
        ten_silent = sdo_round_trips(port, 300)
        wait_until(lambda: twin.stderr().count("client does not read its data: dropped") >= 10,
                   60.0, interval=0.2, what="the 10 silent clients dropped")
    finally:
        stop.set()
        for t in threads:
            t.join(2)
        for s in readers + silent + [producer]:
            s.close()
    p50_all, p50_silent = statistics.median(all_reading), statistics.median(ten_silent)
    print(f"SDO round trip p50 with 89 readers {p50_all * 1e6:.0f} µs, with 10 more that never "
          f"read {p50_silent * 1e6:.0f} µs")
    # Within noise: the silent clients cost the loop no more than readers do.
    assert p50_silent < 1.5 * p50_all + 0.0002, (p50_all, p50_silent)
    assert twin.stderr().count("client does not read its data: dropped") == 10
    assert twin.running()


def test_a_flooding_client_is_held_to_the_bus_rate(launch, tmp_path):
    """A client that sends frames as fast as TCP takes them gets the bus's frame rate (1 Mbit/s
    / 47 bits on the instant bus) and no more; the rest is dropped, logged once; another
    client's SDO round trips stay bounded and it keeps up with the frames it is sent."""
    twin = launch(config=cell_file(tmp_path, 1000))
    port = twin.port
    flood = handshake(port)
    flood.setblocking(False)
    watcher = handshake(port)
    watcher.setblocking(False)
    stop = threading.Event()
    counts = {"sent": 0, "seen": 0}

    def flood_bus():
        frame = b"< send 123 8 01 02 03 04 05 06 07 08 >"
        burst = frame * 256
        while not stop.is_set():
            try:
                n = flood.send(burst)
                counts["sent"] += n // len(frame)
            except BlockingIOError:
                time.sleep(0.0002)
            except OSError:
                return
            try:
                flood.recv(1 << 16)
            except (BlockingIOError, ConnectionError):
                pass

    def watch():
        tail = b""
        while not stop.is_set():
            try:
                chunk = watcher.recv(1 << 20)
            except BlockingIOError:
                time.sleep(0.0005)
                continue
            except OSError:
                return
            data = tail + chunk
            counts["seen"] += data.count(b"< frame 123 ")
            tail = data[-16:]

    threads = [threading.Thread(target=f, daemon=True) for f in (flood_bus, watch)]
    for t in threads:
        t.start()
    try:
        time.sleep(0.5)
        start_seen, t0 = counts["seen"], time.monotonic()
        during = sdo_round_trips(port, 200)
        time.sleep(max(0.0, 2.0 - (time.monotonic() - t0)))
        seen, elapsed = counts["seen"] - start_seen, time.monotonic() - t0
    finally:
        stop.set()
        for t in threads:
            t.join(2)
        flood.close()
        watcher.close()
    rate = seen / elapsed
    print(f"flood: {counts['sent']} frames sent, {rate:.0f} frames/s on the bus; "
          f"SDO p50 {statistics.median(during) * 1e6:.0f} µs")
    assert counts["sent"] > 2 * rate * elapsed, "the client did flood"
    assert rate <= 1_000_000 / 47 * 1.1, rate
    assert statistics.median(during) < 0.005, statistics.median(during)
    log = twin.stderr()
    assert log.count("client sends faster than the bus carries") == 1, log[-2000:]
    assert twin.running()
