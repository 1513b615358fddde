"""The live link in Blender: packets over a loopback socket drive the AU shape keys."""
import socket
import time

import pytest

MODULE = "bl_ext.pdeface_test.pdeface"


def live():
    return __import__(MODULE + ".live", fromlist=["live"])


def wait_for(cond, timeout=5.0):
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def test_live_link_drives_and_records_the_face(bpy, face):
    s = bpy.context.scene.pdeface
    s.live_port, s.live_mode, s.live_record, s.live_hz = 0, "queue", True, 60
    assert bpy.ops.pdeface.live_start() == {"FINISHED"}
    link = live()
    try:
        st = link.status()
        assert st["running"] and st["address"][0] == "127.0.0.1"
        sock = socket.create_connection(tuple(st["address"]), timeout=5)
        sock.sendall(b"{12}{45L:0.5,99}garbage{1,2}")
        wait_for(lambda: link.status()["packets"] == 3)
        kb = face.data.shape_keys.key_blocks
        bpy.context.scene.frame_set(1)
        deadline = time.monotonic() + 5
        while kb["AU12 Lip Corner Puller"].value < 1.0:  # the timer's work, called directly (no event loop headless)
            assert time.monotonic() < deadline
            link.tick()
            time.sleep(0.02)
        deadline = time.monotonic() + 5
        while not (kb["AU1 Inner Brow Raiser"].value == 1.0 and kb["AU2 Outer Brow Raiser"].value == 1.0):
            assert time.monotonic() < deadline
            link.tick()
            time.sleep(0.02)
        assert kb["AU12 Lip Corner Puller"].value == 0.0 and kb["AU45L Blink"].value == 0.0
        st = link.status()
        assert st["played"] == 3 and st["garbage"] >= 1 and 99 in st["unknown_aus"]
        assert face.data.shape_keys.animation_data is not None  # recorded into keyframes
        sock.close()
    finally:
        bpy.ops.pdeface.live_stop()
    assert not link.running()
    with pytest.raises(RuntimeError, match="not running|context is incorrect"):
        bpy.ops.pdeface.live_stop()


def test_live_link_refuses_to_open_to_the_network_unasked(bpy, face):
    s = bpy.context.scene.pdeface
    s.live_host = "0.0.0.0"
    with pytest.raises(RuntimeError, match="Allow remote"):
        bpy.ops.pdeface.live_start()
    assert not live().running()
    s.live_host = "127.0.0.1"
    with socket.create_server(("127.0.0.1", 0)) as taken:  # a port someone else listens on
        s.live_port = taken.getsockname()[1]
        with pytest.raises(RuntimeError, match="cannot listen"):
            bpy.ops.pdeface.live_start()
    assert not live().running()


def test_live_link_token_keeps_strangers_from_stopping_it(bpy, face):
    s = bpy.context.scene.pdeface
    s.live_port, s.live_mode, s.live_record, s.live_token = 0, "live", False, "s3cret"
    assert bpy.ops.pdeface.live_start() == {"FINISHED"}
    link = live()
    try:
        address = tuple(link.status()["address"])
        with socket.create_connection(address, timeout=5) as stranger:
            stranger.sendall(b"{12} -4 -4x -2\n")
            wait_for(lambda: link.status()["controls_refused"] == 2)
            assert not link.status()["stopped"] and link.status()["packets"] == 1
        with socket.create_connection(address, timeout=5) as owner:
            owner.sendall(b'{"auth": "s3cret"}\n-4 ')
            wait_for(lambda: link.status()["stopped"])
    finally:
        s.live_token = ""
        bpy.ops.pdeface.live_stop()
