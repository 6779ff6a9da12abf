// Procedural test images for feature and matching tests: random rectangles, ellipses, lines
// and multi-scale noise blobs drawn with OpenCV from a fixed seed, plus views of that texture
// warped by known homographies, which give exact ground-truth correspondences.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

namespace ccm::test {

/// Deterministic textured grey image of the given size.
cv::Mat MakeTexture(int width, int height, uint64_t seed);

/// Homography of a rotation by angle_deg and a zoom by `scale` about `center` (dst = H src).
cv::Matx33d RotateScaleAbout(cv::Point2d center, double angle_deg, double scale);

/// Pure translation homography.
cv::Matx33d Translation(double dx, double dy);

/// dst image of size `size` showing `texture` through view_from_texture (warpPerspective,
/// bilinear). Pixel centres are integer coordinates on both sides.
cv::Mat RenderView(const cv::Mat& texture, const cv::Matx33d& view_from_texture, cv::Size size);

/// Applies a homography to a point.
cv::Point2d Apply(const cv::Matx33d& h, cv::Point2d p);

}  // namespace ccm::test
