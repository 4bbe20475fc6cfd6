"""Corner detection from images (the camera extra): a board rendered through a known homography is found where the
homography puts its corners."""
import numpy as np
import pytest

from robocal.io import opencv_extra
from robocal.io.camera_target import target_from_dict
from robocal.io.image_detection import detect_images

pytestmark = pytest.mark.skipif(not opencv_extra.has("aruco.CharucoDetector", "findChessboardCorners"),
                                reason="needs the camera extra (opencv-python-headless>=4.8)")
PX_PER_M = 2500.0        # board pixels per metre in the flat rendering


def _render(cv2, board_image, H, path):
    warped = cv2.warpPerspective(board_image, H, (1280, 1024), borderValue=255)
    cv2.imwrite(str(path), warped)


@pytest.mark.parametrize("kind", ["checkerboard", "charuco"])
def test_detected_corners_lie_where_the_homography_puts_them(kind, tmp_path):
    cv2 = opencv_extra.opencv()
    if kind == "charuco":
        spec = {"type": "charuco", "squares": [7, 5], "square": 0.04, "marker": 0.03, "dictionary": "DICT_5X5_100"}
        target = target_from_dict(spec)
        board = cv2.aruco.CharucoBoard((7, 5), 0.04, 0.03, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100))
        flat = board.generateImage((int(0.28 * PX_PER_M), int(0.20 * PX_PER_M)))
        origin = np.zeros(2)
    else:
        target = target_from_dict({"type": "checkerboard", "corners": [8, 5], "square": 0.03})
        s = int(0.03 * PX_PER_M)
        flat = np.kron((np.indices((6, 9)).sum(axis=0) % 2) * 255, np.ones((s, s))).astype(np.uint8)
        flat = cv2.copyMakeBorder(flat, s, s, s, s, cv2.BORDER_CONSTANT, value=255)
        origin = np.array([2 * s, 2 * s])      # the first inner corner, in flat pixels
    paths, truth = [], []
    for n in range(3):
        H = np.array([[1.0 + 0.1 * n, 0.05, 150.0], [-0.04, 0.95, 120.0 + 30 * n], [2e-5 * n, 1e-5, 1.0]])
        path = tmp_path / f"img{n}.png"
        _render(cv2, flat, H, path)
        paths.append(path)
        # a corner sits on a pixel boundary: OpenCV puts pixel centres at integers, so boundaries at k - 0.5
        flat_px = origin + target.points[:, :2] * PX_PER_M - 0.5
        h = np.column_stack([flat_px, np.ones(len(flat_px))]) @ H.T
        truth.append(h[:, :2] / h[:, 2:])
    det, notes = detect_images(paths, target)
    assert not notes
    for n, path in enumerate(paths):
        rows = det.samples == path.stem
        assert rows.sum() >= 0.75 * len(target.ids)      # ChArUco may miss corners by the edge
        # rendering (bilinear warp of a 2500 px/m board) places a corner within about half a pixel
        err = np.linalg.norm(det.uv[rows] - truth[n][det.corners[rows]], axis=1)
        assert np.median(err) < 0.5 and err.max() < 1.5, (kind, n, err.max())
