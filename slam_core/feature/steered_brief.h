// Orientation and rotated BRIEF descriptor of ORB. The 256 point pairs are drawn once from
// an isotropic Gaussian (BRIEF's "G II" layout, sigma = patch / 5) by a fixed-seed generator
// of our own, so they are reproducible on every platform and not copied from any library.
#pragma once

#include <opencv2/core.hpp>

#include "slam_core/feature/orb_types.h"

namespace ccm {

/// Patch radius of the intensity-centroid orientation [px].
constexpr int kOrientationRadius = 15;
/// Every pattern point lies within this radius of the keypoint, before and after rotation.
constexpr int kPatternRadius = 13;
/// Keypoints must be at least this far from the image border for both patches.
constexpr int kMinPatchBorder = kOrientationRadius + 1;

/// Intensity-centroid angle [deg, 0..360) of the circular patch of radius 15 around (x, y).
/// (x, y) must be >= kMinPatchBorder from the border.
float IntensityCentroidAngle(const cv::Mat& gray, int x, int y);

/// Steered BRIEF of the (already smoothed) image at (x, y) with orientation angle_deg.
OrbDescriptor SteeredBrief(const cv::Mat& smoothed, int x, int y, float angle_deg);

}  // namespace ccm
