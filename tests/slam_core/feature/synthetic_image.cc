#include "synthetic_image.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

namespace ccm::test {

cv::Mat MakeTexture(int width, int height, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat img(height, width, CV_8UC1, cv::Scalar(128));
  // Smooth multi-scale noise as background so no region is flat.
  for (int cell : {64, 16, 4}) {
    cv::Mat small(height / cell + 2, width / cell + 2, CV_8UC1);
    rng.fill(small, cv::RNG::UNIFORM, 0, 256);
    cv::Mat up;
    cv::resize(small, up, cv::Size(width + 2 * cell, height + 2 * cell), 0, 0, cv::INTER_CUBIC);
    cv::addWeighted(img, 0.6, up(cv::Rect(cell, cell, width, height)), 0.4, 0, img);
  }
  const int area = width * height;
  const int num_shapes = area / 700;
  for (int i = 0; i < num_shapes; ++i) {
    // Log-uniform sizes: many small shapes, a few large ones.
    const double size = std::exp(rng.uniform(std::log(3.0), std::log(90.0)));
    const cv::Point c(rng.uniform(0, width), rng.uniform(0, height));
    const cv::Scalar color(rng.uniform(0, 256));
    switch (rng.uniform(0, 4)) {
      case 0: {
        const cv::Point d(static_cast<int>(size * rng.uniform(0.3, 1.0)),
                          static_cast<int>(size * rng.uniform(0.3, 1.0)));
        cv::rectangle(img, c - d, c + d, color, cv::FILLED, cv::LINE_AA);
        break;
      }
      case 1:
        cv::ellipse(
            img, c,
            cv::Size(static_cast<int>(size), static_cast<int>(size * rng.uniform(0.2, 1.0))),
            rng.uniform(0.0, 180.0), 0, 360, color, cv::FILLED, cv::LINE_AA);
        break;
      case 2: {
        const double a = rng.uniform(0.0, CV_PI);
        const cv::Point d(static_cast<int>(size * std::cos(a)),
                          static_cast<int>(size * std::sin(a)));
        cv::line(img, c - d, c + d, color, rng.uniform(1, 4), cv::LINE_AA);
        break;
      }
      default: {
        std::vector<cv::Point> poly;
        for (int k = 0; k < 3; ++k) {
          poly.emplace_back(c.x + static_cast<int>(rng.uniform(-size, size)),
                            c.y + static_cast<int>(rng.uniform(-size, size)));
        }
        cv::fillConvexPoly(img, poly, color, cv::LINE_AA);
      }
    }
  }
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0.7);
  return img;
}

cv::Matx33d RotateScaleAbout(cv::Point2d center, double angle_deg, double scale) {
  const double a = angle_deg * CV_PI / 180.0;
  const double c = scale * std::cos(a), s = scale * std::sin(a);
  // p' = center + S R (p - center)
  return cv::Matx33d(c, -s, center.x - c * center.x + s * center.y,  //
                     s, c, center.y - s * center.x - c * center.y,   //
                     0, 0, 1);
}

cv::Matx33d Translation(double dx, double dy) { return cv::Matx33d(1, 0, dx, 0, 1, dy, 0, 0, 1); }

cv::Mat RenderView(const cv::Mat& texture, const cv::Matx33d& view_from_texture, cv::Size size) {
  cv::Mat view;
  cv::warpPerspective(texture, view, cv::Mat(view_from_texture), size, cv::INTER_LINEAR,
                      cv::BORDER_REFLECT_101);
  return view;
}

cv::Point2d Apply(const cv::Matx33d& h, cv::Point2d p) {
  const cv::Vec3d q = h * cv::Vec3d(p.x, p.y, 1.0);
  return {q[0] / q[2], q[1] / q[2]};
}

}  // namespace ccm::test
