"""Display backends: pixel formats and the framebuffer as sysfs describes it."""

import numpy as np
import pytest

import cv2

from feelium.projector.display import DisplayUnavailable, FbdevDisplay, SimDisplay, open_display


def _fake_fb(tmp_path, size="8,4", bpp="16", stride=None):
    sysfs = tmp_path / "sys" / "fb0"
    sysfs.mkdir(parents=True)
    (sysfs / "virtual_size").write_text(size + "\n")
    (sysfs / "bits_per_pixel").write_text(bpp + "\n")
    if stride:
        (sysfs / "stride").write_text(stride)
    device = tmp_path / "fb0"
    w, h = (int(v) for v in size.split(","))
    device.write_bytes(bytes(int(stride) * h if stride else w * h * int(bpp) // 8))  # a device's fixed size
    return str(device), str(tmp_path / "sys")


@pytest.mark.parametrize("bpp, stride, bytes_per_px", [("16", None, 2), ("32", "40", 4)])
def test_fbdev_writes_letterboxed_frames_in_the_device_format(tmp_path, bpp, stride, bytes_per_px):
    device, sysfs = _fake_fb(tmp_path, "8,4", bpp, stride)
    display = FbdevDisplay(device, sysfs)
    frame = np.zeros((2, 2, 3), np.uint8)
    frame[:] = (0, 0, 255)  # red, scaled to 4x4 and centred in 8x4
    display.show(frame)
    display.close()
    raw = np.frombuffer(open(device, "rb").read(), np.uint8)
    row = int(stride) if stride else 8 * bytes_per_px
    assert raw.size == 4 * row
    rows = raw.reshape(4, row)
    if bpp == "16":
        px = rows[:, :16].copy().view("<u2")
        assert px[0].tolist() == [0, 0, 0xF800, 0xF800, 0xF800, 0xF800, 0, 0]
    else:
        px = rows[:, :32].reshape(4, 8, 4)
        assert px[1, 3, :3].tolist() == [0, 0, 255] and px[1, 0, :3].tolist() == [0, 0, 0]


def test_fbdev_refuses_unsupported_depth_and_missing_device(tmp_path):
    device, sysfs = _fake_fb(tmp_path, "8,4", "24")
    with pytest.raises(DisplayUnavailable, match="24 bits"):
        FbdevDisplay(device, sysfs)
    with pytest.raises(DisplayUnavailable, match="virtual_size"):
        FbdevDisplay(str(tmp_path / "fb9"), sysfs)


def test_auto_falls_back_to_sim_without_a_framebuffer(tmp_path):
    display = open_display("auto", str(tmp_path / "no-fb"))
    assert isinstance(display, SimDisplay)
    display.show(np.zeros((2, 2, 3), np.uint8))
    assert display.frames == 1 and display.last is not None


def _opencv_has_gui() -> bool:
    info = cv2.getBuildInformation()
    gui = next((line for line in info.splitlines() if line.strip().startswith("GUI:")), "GUI: NONE")
    return "NONE" not in gui


@pytest.mark.skipif(_opencv_has_gui(), reason="this OpenCV has a GUI; the window would open")
def test_window_backend_explains_a_headless_opencv():
    with pytest.raises(DisplayUnavailable, match="no GUI"):
        open_display("window", "/dev/fb0")


def test_fbdev_writes_the_same_frame_once_and_a_new_array_again(tmp_path):
    device, sysfs = _fake_fb(tmp_path, "8,4", "16")
    display = FbdevDisplay(device, sysfs)
    frame = np.full((4, 8, 3), 255, np.uint8)
    display.show(frame)
    assert open(device, "rb").read() == b"\xff" * 64
    with open(device, "r+b") as fb:
        fb.write(bytes(64))  # forget what was written: a repeat must not write again
    display.show(frame)
    assert open(device, "rb").read() == bytes(64) and (display.frames, display.repeats) == (1, 1)
    display.show(frame.copy())
    assert open(device, "rb").read() == b"\xff" * 64 and display.frames == 2
    display.close()


def test_fbdev_clears_the_letterbox_bars_when_the_frame_size_changes(tmp_path, caplog):
    device, sysfs = _fake_fb(tmp_path, "8,4", "32")
    display = FbdevDisplay(device, sysfs)
    display.show(np.full((4, 8, 3), 255, np.uint8))  # the whole screen white
    assert not caplog.records
    display.show(np.full((2, 2, 3), 255, np.uint8))  # a square: scaled to 4x4, centred, bars black
    display.show(np.full((2, 2, 3), 255, np.uint8))
    assert len(caplog.records) == 1 and "scaled on the CPU" in caplog.records[0].getMessage()  # once, not per frame
    pixels = np.frombuffer(open(device, "rb").read(), np.uint8).reshape(4, 8, 4)
    assert (pixels[:, :2] == 0).all() and (pixels[:, 6:] == 0).all() and (pixels[:, 2:6, :3] == 255).all()
    display.close()


def test_fbdev_refuses_a_device_too_small_for_its_geometry_and_a_closed_display(tmp_path):
    device, sysfs = _fake_fb(tmp_path, "8,4", "16")
    open(device, "wb").close()  # 0 bytes: nothing to map
    with pytest.raises(DisplayUnavailable, match="cannot map"):
        FbdevDisplay(device, sysfs)
    device, sysfs = _fake_fb(tmp_path / "b", "8,4", "16")
    display = FbdevDisplay(device, sysfs)
    display.close()
    display.close()  # twice is harmless
    with pytest.raises(DisplayUnavailable, match="closed"):
        display.show(np.zeros((4, 8, 3), np.uint8))


def _shown(tmp_path, frame, bpp):
    h, w = frame.shape[:2]
    device, sysfs = _fake_fb(tmp_path / bpp, f"{w},{h}", bpp)
    display = FbdevDisplay(device, sysfs)
    display.show(frame)
    display.close()
    return open(device, "rb").read()


def test_16_bits_are_rgb565_little_endian_red_high_blue_low(tmp_path):
    frame = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]], np.uint8)  # blue, green, red, white
    assert np.frombuffer(_shown(tmp_path, frame, "16"), "<u2").tolist() == [0x001F, 0x07E0, 0xF800, 0xFFFF]
    frame = np.random.default_rng(3).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    b, g, r = (frame[:, :, i].astype(np.uint16) for i in range(3))
    expected = ((r >> 3) << 11) | ((g >> 2) << 5) | (b >> 3)
    assert np.array_equal(np.frombuffer(_shown(tmp_path / "random", frame, "16"), "<u2").reshape(5, 7), expected)


def test_32_bits_are_bytes_b_g_r_x(tmp_path):
    frame = np.random.default_rng(4).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    assert np.array_equal(np.frombuffer(_shown(tmp_path, frame, "32"), np.uint8).reshape(5, 7, 4)[:, :, :3], frame)
