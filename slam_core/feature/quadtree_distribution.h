// Spreads corners evenly over an image region: the region is split into quadtree nodes until
// there are about `target` nodes (largest nodes first), then each node keeps its strongest
// corner. Used per pyramid level by OrbExtractor so a textured corner of the image cannot
// take all the keypoints.
#pragma once

#include <opencv2/core/types.hpp>
#include <vector>

namespace ccm {

/// Returns indices into `corners` (at most `target`, strongest first) of the kept corners.
/// The region is [x0, x1) x [y0, y1); corners outside it are ignored. Deterministic: ties in
/// response are broken by index.
std::vector<int> DistributeQuadtree(const std::vector<cv::KeyPoint>& corners, float x0, float y0,
                                    float x1, float y1, int target);

}  // namespace ccm
