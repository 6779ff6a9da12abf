#include "slam_core/feature/quadtree_distribution.h"

#include <algorithm>
#include <cmath>

namespace ccm {
namespace {

struct Node {
  float x0, y0, x1, y1;
  std::vector<int> items;
};

/// Splits a node into its four quadrants; empty quadrants are dropped.
void Split(const Node& node, const std::vector<cv::KeyPoint>& corners, std::vector<Node>* out) {
  const float xm = 0.5f * (node.x0 + node.x1), ym = 0.5f * (node.y0 + node.y1);
  Node child[4] = {{node.x0, node.y0, xm, ym, {}},
                   {xm, node.y0, node.x1, ym, {}},
                   {node.x0, ym, xm, node.y1, {}},
                   {xm, ym, node.x1, node.y1, {}}};
  for (int i : node.items) {
    const cv::Point2f& p = corners[i].pt;
    child[(p.x >= xm ? 1 : 0) + (p.y >= ym ? 2 : 0)].items.push_back(i);
  }
  for (Node& c : child) {
    if (!c.items.empty()) out->push_back(std::move(c));
  }
}

bool Stronger(const std::vector<cv::KeyPoint>& corners, int a, int b) {
  if (corners[a].response != corners[b].response) return corners[a].response > corners[b].response;
  return a < b;
}

/// Initial nodes: a row of roughly square nodes across the region.
std::vector<Node> InitialNodes(const std::vector<cv::KeyPoint>& corners, float x0, float y0,
                               float x1, float y1) {
  const int n = std::max(1, static_cast<int>(std::lround((x1 - x0) / (y1 - y0))));
  const float w = (x1 - x0) / n;
  std::vector<Node> nodes(n);
  for (int k = 0; k < n; ++k) nodes[k] = {x0 + k * w, y0, x0 + (k + 1) * w, y1, {}};
  for (int i = 0; i < static_cast<int>(corners.size()); ++i) {
    const cv::Point2f& p = corners[i].pt;
    if (p.x < x0 || p.x >= x1 || p.y < y0 || p.y >= y1) continue;
    nodes[std::min(n - 1, static_cast<int>((p.x - x0) / w))].items.push_back(i);
  }
  nodes.erase(
      std::remove_if(nodes.begin(), nodes.end(), [](const Node& nd) { return nd.items.empty(); }),
      nodes.end());
  return nodes;
}

}  // namespace

std::vector<int> DistributeQuadtree(const std::vector<cv::KeyPoint>& corners, float x0, float y0,
                                    float x1, float y1, int target) {
  if (target <= 0 || x1 <= x0 || y1 <= y0) return {};
  std::vector<Node> nodes = InitialNodes(corners, x0, y0, x1, y1);
  // Each round splits the most populated nodes first and stops as soon as there are enough
  // nodes, so the dense parts of the image are subdivided before the sparse ones.
  while (static_cast<int>(nodes.size()) < target) {
    std::vector<int> order;
    for (int k = 0; k < static_cast<int>(nodes.size()); ++k) {
      const Node& nd = nodes[k];
      if (nd.items.size() > 1 && nd.x1 - nd.x0 > 0.5f) order.push_back(k);
    }
    if (order.empty()) break;
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return nodes[a].items.size() > nodes[b].items.size(); });
    std::vector<bool> split(nodes.size(), false);
    std::vector<Node> next;
    int count = static_cast<int>(nodes.size());
    for (int k : order) {
      if (count >= target) break;
      const size_t before = next.size();
      Split(nodes[k], corners, &next);
      count += static_cast<int>(next.size() - before) - 1;
      split[k] = true;
    }
    for (size_t k = 0; k < nodes.size(); ++k) {
      if (!split[k]) next.push_back(std::move(nodes[k]));
    }
    nodes = std::move(next);
  }
  std::vector<int> kept;
  kept.reserve(nodes.size());
  for (const Node& nd : nodes) {
    int best = nd.items.front();
    for (int i : nd.items) {
      if (Stronger(corners, i, best)) best = i;
    }
    kept.push_back(best);
  }
  std::sort(kept.begin(), kept.end(), [&](int a, int b) { return Stronger(corners, a, b); });
  if (static_cast<int>(kept.size()) > target) kept.resize(target);
  return kept;
}

}  // namespace ccm
