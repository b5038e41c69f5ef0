"""Display backends: pixel formats and the framebuffer as sysfs describes it."""

import numpy as np
import pytest

import cv2

from feelium.projector.display import DisplayUnavailable, FbdevDisplay, SimDisplay, open_display, to_bgr565, to_xrgb8888


def test_bgr565_packs_red_high_and_blue_low():
    frame = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]], np.uint8)  # blue, green, red, white
    assert to_bgr565(frame).tolist() == [[0x001F, 0x07E0, 0xF800, 0xFFFF]]


def test_xrgb8888_byte_order_is_b_g_r_x():
    frame = np.array([[[1, 2, 3]]], np.uint8)
    assert to_xrgb8888(frame)[0, 0, :3].tolist() == [1, 2, 3]


def _fake_fb(tmp_path, size="8,4", bpp="16", stride=None):
    sysfs = tmp_path / "sys" / "fb0"
    sysfs.mkdir(parents=True)
    (sysfs / "virtual_size").write_text(size + "\n")
    (sysfs / "bits_per_pixel").write_text(bpp + "\n")
    if stride:
        (sysfs / "stride").write_text(stride)
    device = tmp_path / "fb0"
    device.write_bytes(b"")
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
    open(device, "wb").close()  # forget what was written: a repeat must not write again
    display.show(frame)
    assert open(device, "rb").read() == b"" and (display.frames, display.repeats) == (1, 1)
    display.show(frame.copy())
    assert len(open(device, "rb").read()) == 4 * 8 * 2 and display.frames == 2
    display.close()
