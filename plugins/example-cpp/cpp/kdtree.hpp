// A 3D kd-tree over a fixed point set, for the example plugin's nearest-neighbour and k-nearest
// queries: median splits on the widest axis, leaves of up to eight points, exact search with pruning.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <limits>
#include <queue>
#include <vector>

namespace skid_example {

using Vec3 = std::array<double, 3>;

inline double squared_distance(const Vec3& a, const Vec3& b) {
    const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

class KdTree {
public:
    explicit KdTree(const std::vector<Vec3>& points) : points_(points) {
        indices_.resize(points.size());
        for (std::size_t i = 0; i < points.size(); ++i) indices_[i] = i;
        if (!points.empty()) root_ = build(0, points.size());
    }

    // The index of the nearest point within sqrt(max_squared) of `query`, or -1.
    long nearest(const Vec3& query, double max_squared, double* found_squared) const {
        long best = -1;
        double best_squared = max_squared;
        if (root_ >= 0) nearest_in(root_, query, best, best_squared);
        if (found_squared != nullptr) *found_squared = best_squared;
        return best;
    }

    // The indices of the up to k nearest points to `query`, nearest last.
    void knn(const Vec3& query, std::size_t k, std::vector<std::size_t>& out) const {
        std::priority_queue<std::pair<double, std::size_t>> heap;  // Largest distance on top.
        if (root_ >= 0 && k > 0) knn_in(root_, query, k, heap);
        out.clear();
        while (!heap.empty()) {
            out.push_back(heap.top().second);
            heap.pop();
        }
    }

private:
    struct Node {
        std::size_t begin = 0, end = 0;  // Leaf range in indices_ when axis < 0.
        int axis = -1;
        double split = 0.0;
        long left = -1, right = -1;
    };

    long build(std::size_t begin, std::size_t end) {
        Node node;
        node.begin = begin;
        node.end = end;
        if (end - begin > kLeafSize) {
            Vec3 low{}, high{};
            low.fill(std::numeric_limits<double>::infinity());
            high.fill(-std::numeric_limits<double>::infinity());
            for (std::size_t i = begin; i < end; ++i) {
                for (int a = 0; a < 3; ++a) {
                    low[a] = std::min(low[a], points_[indices_[i]][a]);
                    high[a] = std::max(high[a], points_[indices_[i]][a]);
                }
            }
            int axis = 0;
            for (int a = 1; a < 3; ++a) {
                if (high[a] - low[a] > high[axis] - low[axis]) axis = a;
            }
            const std::size_t middle = begin + (end - begin) / 2;
            std::nth_element(indices_.begin() + static_cast<long>(begin), indices_.begin() + static_cast<long>(middle),
                             indices_.begin() + static_cast<long>(end),
                             [&](std::size_t a, std::size_t b) { return points_[a][axis] < points_[b][axis]; });
            node.axis = axis;
            node.split = points_[indices_[middle]][axis];
            const long id = static_cast<long>(nodes_.size());
            nodes_.push_back(node);
            const long left = build(begin, middle);
            const long right = build(middle, end);
            nodes_[static_cast<std::size_t>(id)].left = left;
            nodes_[static_cast<std::size_t>(id)].right = right;
            return id;
        }
        nodes_.push_back(node);
        return static_cast<long>(nodes_.size()) - 1;
    }

    void nearest_in(long id, const Vec3& query, long& best, double& best_squared) const {
        const Node& node = nodes_[static_cast<std::size_t>(id)];
        if (node.axis < 0) {
            for (std::size_t i = node.begin; i < node.end; ++i) {
                const double d = squared_distance(points_[indices_[i]], query);
                if (d < best_squared) {
                    best_squared = d;
                    best = static_cast<long>(indices_[i]);
                }
            }
            return;
        }
        const double offset = query[node.axis] - node.split;
        const long near = offset < 0.0 ? node.left : node.right;
        const long far = offset < 0.0 ? node.right : node.left;
        nearest_in(near, query, best, best_squared);
        if (offset * offset < best_squared) nearest_in(far, query, best, best_squared);
    }

    void knn_in(long id, const Vec3& query, std::size_t k,
                std::priority_queue<std::pair<double, std::size_t>>& heap) const {
        const Node& node = nodes_[static_cast<std::size_t>(id)];
        if (node.axis < 0) {
            for (std::size_t i = node.begin; i < node.end; ++i) {
                const double d = squared_distance(points_[indices_[i]], query);
                if (heap.size() < k) {
                    heap.emplace(d, indices_[i]);
                } else if (d < heap.top().first) {
                    heap.pop();
                    heap.emplace(d, indices_[i]);
                }
            }
            return;
        }
        const double offset = query[node.axis] - node.split;
        const long near = offset < 0.0 ? node.left : node.right;
        const long far = offset < 0.0 ? node.right : node.left;
        knn_in(near, query, k, heap);
        if (heap.size() < k || offset * offset < heap.top().first) knn_in(far, query, k, heap);
    }

    static constexpr std::size_t kLeafSize = 8;
    const std::vector<Vec3>& points_;
    std::vector<std::size_t> indices_;
    std::vector<Node> nodes_;
    long root_ = -1;
};

}  // namespace skid_example
