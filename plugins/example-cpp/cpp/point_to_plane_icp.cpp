// An out-of-tree SKiD fine-registration plugin written in C++17 against the generated C header
// (framework/abi/include/skid_plugin.h): point-to-plane ICP (Chen and Medioni 1992) with a coarse-to-fine
// schedule of correspondence distances, solved by Gauss-Newton on SE(3).
//
// prepare() voxel-downsamples a cloud (centroid per voxel), builds a kd-tree and estimates a normal per
// point from its k nearest neighbours (the smallest eigenvector of their covariance; neighbourhoods that
// are not planar, such as a line, get no normal). refine() pairs every source point with its nearest
// target point that has a normal, minimises the sum of squared point-to-plane distances, shrinks the
// correspondence distance from 4x to 1x max_correspondence_m, and reports the Gauss-Newton Hessian as
// the information (translation first). It refuses to claim convergence with too few correspondences or a
// Hessian that does not constrain all six degrees of freedom.
//
// Every exported function catches every exception: nothing unwinds into the host.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "kdtree.hpp"
#include "linalg.hpp"
#include "skid_plugin.h"

namespace skid_example {
namespace {

constexpr const char* kName = "point_to_plane_icp";
constexpr const char* kSummary = "Point-to-plane ICP with a coarse-to-fine distance schedule (C++17 example plugin)";
constexpr const char* kDefaultConfig =
    "downsampling_m = 0.25\n"
    "max_correspondence_m = 1.0\n"
    "num_neighbors = 10\n"
    "max_iterations = 30\n"
    "min_inliers = 30\n"
    "translation_eps_m = 0.0001\n"
    "rotation_eps_deg = 0.01\n";

// A config key the plugin refuses, and why.
struct ConfigError {
    std::string key;
    std::string message;
};

struct Config {
    double downsampling_m = 0.25;
    double max_correspondence_m = 1.0;
    long num_neighbors = 10;
    long max_iterations = 30;
    long min_inliers = 30;
    double translation_eps_m = 1e-4;
    double rotation_eps_deg = 0.01;
};

std::string trim(const std::string& text) {
    const auto begin = text.find_first_not_of(" \t\r");
    if (begin == std::string::npos) return "";
    const auto end = text.find_last_not_of(" \t\r");
    return text.substr(begin, end - begin + 1);
}

double parse_number(const std::string& key, const std::string& value) {
    std::size_t used = 0;
    double number = 0.0;
    try {
        number = std::stod(value, &used);
    } catch (const std::exception&) {
        throw ConfigError{key, "expected a number, got `" + value + "`"};
    }
    if (used != value.size() || !std::isfinite(number)) throw ConfigError{key, "expected a finite number, got `" + value + "`"};
    return number;
}

long parse_integer(const std::string& key, const std::string& value) {
    const double number = parse_number(key, value);
    if (number != std::floor(number)) throw ConfigError{key, "expected an integer, got `" + value + "`"};
    return static_cast<long>(number);
}

// Reads the flat `key = number` TOML the host sends (the plugin's own table); unknown keys are errors.
Config parse_config(const std::string& text) {
    Config config;
    std::size_t start = 0;
    while (start <= text.size()) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(start, end - start);
        start = end + 1;
        const auto comment = line.find('#');
        if (comment != std::string::npos) line = line.substr(0, comment);
        line = trim(line);
        if (line.empty()) continue;
        const auto equals = line.find('=');
        if (equals == std::string::npos) throw ConfigError{"", "expected `key = value`, got `" + line + "`"};
        const std::string key = trim(line.substr(0, equals));
        const std::string value = trim(line.substr(equals + 1));
        if (key == "downsampling_m") config.downsampling_m = parse_number(key, value);
        else if (key == "max_correspondence_m") config.max_correspondence_m = parse_number(key, value);
        else if (key == "num_neighbors") config.num_neighbors = parse_integer(key, value);
        else if (key == "max_iterations") config.max_iterations = parse_integer(key, value);
        else if (key == "min_inliers") config.min_inliers = parse_integer(key, value);
        else if (key == "translation_eps_m") config.translation_eps_m = parse_number(key, value);
        else if (key == "rotation_eps_deg") config.rotation_eps_deg = parse_number(key, value);
        else
            throw ConfigError{key,
                              "unknown key; expected one of downsampling_m, max_correspondence_m, num_neighbors, "
                              "max_iterations, min_inliers, translation_eps_m, rotation_eps_deg"};
    }
    if (config.downsampling_m < 0.0) throw ConfigError{"downsampling_m", "must be >= 0"};
    if (!(config.max_correspondence_m > 0.0)) throw ConfigError{"max_correspondence_m", "must be > 0"};
    if (config.num_neighbors < 3 || config.num_neighbors > 100) throw ConfigError{"num_neighbors", "must be between 3 and 100"};
    if (config.max_iterations < 1 || config.max_iterations > 1000) throw ConfigError{"max_iterations", "must be between 1 and 1000"};
    if (config.min_inliers < 6) throw ConfigError{"min_inliers", "must be at least 6"};
    if (!(config.translation_eps_m > 0.0)) throw ConfigError{"translation_eps_m", "must be > 0"};
    if (!(config.rotation_eps_deg > 0.0)) throw ConfigError{"rotation_eps_deg", "must be > 0"};
    return config;
}

// A cloud as refine() needs it; never changed after prepare(), so refine() may share it across threads.
struct Prepared {
    std::vector<SkidPoint> kept;       // The downsampled points, shown to the host.
    std::vector<Vec3> points;          // The same, in double precision.
    std::vector<Vec3> normals;         // Unit normals; valid only where has_normal is set.
    std::vector<unsigned char> has_normal;
    std::unique_ptr<KdTree> tree;      // Over `points`, which it references.
};

struct Instance {
    Config config;
};

// Centroid per voxel of `size_m` (no downsampling when 0); non-finite points are skipped.
std::vector<SkidPoint> downsample(const SkidPoint* points, std::size_t count, double size_m) {
    std::vector<SkidPoint> out;
    if (size_m <= 0.0) {
        for (std::size_t i = 0; i < count; ++i) {
            if (std::isfinite(points[i].x) && std::isfinite(points[i].y) && std::isfinite(points[i].z)) out.push_back(points[i]);
        }
        return out;
    }
    struct Sum {
        double x = 0, y = 0, z = 0, intensity = 0;
        std::size_t n = 0;
    };
    std::unordered_map<std::int64_t, std::size_t> cell_of;
    std::vector<Sum> sums;
    for (std::size_t i = 0; i < count; ++i) {
        const SkidPoint& p = points[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
        const auto cell = [&](float v) { return static_cast<std::int64_t>(std::floor(v / size_m)) & 0x1FFFFF; };
        const std::int64_t key = (cell(p.x) << 42) | (cell(p.y) << 21) | cell(p.z);
        const auto found = cell_of.emplace(key, sums.size());
        if (found.second) sums.emplace_back();
        Sum& sum = sums[found.first->second];
        sum.x += p.x;
        sum.y += p.y;
        sum.z += p.z;
        sum.intensity += p.intensity;
        ++sum.n;
    }
    out.reserve(sums.size());
    for (const Sum& sum : sums) {
        const double n = static_cast<double>(sum.n);
        SkidPoint p{};
        p.x = static_cast<float>(sum.x / n);
        p.y = static_cast<float>(sum.y / n);
        p.z = static_cast<float>(sum.z / n);
        p.intensity = static_cast<float>(sum.intensity / n);
        out.push_back(p);
    }
    return out;
}

Prepared* prepare_cloud(const Config& config, const SkidPoint* points, std::size_t count) {
    auto prepared = std::make_unique<Prepared>();
    prepared->kept = downsample(points, count, config.downsampling_m);
    prepared->points.reserve(prepared->kept.size());
    for (const SkidPoint& p : prepared->kept) prepared->points.push_back({p.x, p.y, p.z});
    prepared->tree = std::make_unique<KdTree>(prepared->points);
    prepared->normals.assign(prepared->points.size(), Vec3{0, 0, 0});
    prepared->has_normal.assign(prepared->points.size(), 0);
    std::vector<std::size_t> neighbours;
    const std::size_t k = static_cast<std::size_t>(config.num_neighbors);
    for (std::size_t i = 0; i < prepared->points.size(); ++i) {
        prepared->tree->knn(prepared->points[i], k, neighbours);
        if (neighbours.size() < 3) continue;
        Vec3 mean{0, 0, 0};
        for (std::size_t j : neighbours) {
            for (int a = 0; a < 3; ++a) mean[a] += prepared->points[j][a];
        }
        for (double& m : mean) m /= static_cast<double>(neighbours.size());
        Matrix<3> covariance{};
        for (std::size_t j : neighbours) {
            for (int a = 0; a < 3; ++a) {
                for (int b = 0; b < 3; ++b) {
                    covariance[a][b] += (prepared->points[j][a] - mean[a]) * (prepared->points[j][b] - mean[b]);
                }
            }
        }
        std::array<double, 3> values{};
        Matrix<3> vectors{};
        symmetric_eigen<3>(covariance, values, vectors);
        // A plane spreads in two directions: the middle eigenvalue must not vanish against the largest.
        if (!(values[2] > 0.0) || values[1] < 1e-3 * values[2]) continue;
        prepared->normals[i] = {vectors[0][0], vectors[1][0], vectors[2][0]};
        prepared->has_normal[i] = 1;
    }
    return prepared.release();
}

// The outcome of refine(), before it is copied into the host's struct.
struct Outcome {
    Matrix<3> rotation{};
    Vec3 translation{};
    Matrix<6> hessian{};
    bool converged = false;
    std::uint64_t iterations = 0;
    std::uint64_t inliers = 0;
    double error = 0.0;
    std::string failure;
};

Outcome refine_clouds(const Config& config, const Prepared& target, const Prepared& source, const SkidAbiTransform& guess) {
    Outcome outcome;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) outcome.rotation[r][c] = guess.matrix[r * 4 + c];
        outcome.translation[r] = guess.matrix[r * 4 + 3];
    }
    const double rotation_eps = config.rotation_eps_deg * M_PI / 180.0;
    const double schedule[] = {4.0, 2.0, 1.0};
    for (double scale : schedule) {
        const double max_distance = scale * config.max_correspondence_m;
        const double max_squared = max_distance * max_distance;
        bool stage_converged = false;
        for (long iteration = 0; iteration < config.max_iterations; ++iteration) {
            ++outcome.iterations;
            Matrix<6> h{};
            std::array<double, 6> b{};
            std::uint64_t inliers = 0;
            double squared_sum = 0.0;
            for (const Vec3& p : source.points) {
                Vec3 q{};
                for (int r = 0; r < 3; ++r) {
                    q[r] = outcome.rotation[r][0] * p[0] + outcome.rotation[r][1] * p[1] + outcome.rotation[r][2] * p[2] +
                           outcome.translation[r];
                }
                const long nearest = target.tree->nearest(q, max_squared, nullptr);
                if (nearest < 0 || !target.has_normal[static_cast<std::size_t>(nearest)]) continue;
                const Vec3& t = target.points[static_cast<std::size_t>(nearest)];
                const Vec3& n = target.normals[static_cast<std::size_t>(nearest)];
                const double residual = n[0] * (q[0] - t[0]) + n[1] * (q[1] - t[1]) + n[2] * (q[2] - t[2]);
                // Jacobian for the update x = (v, w): q -> q + w x q + v, so d r = n.v + (q x n).w.
                const std::array<double, 6> j = {n[0], n[1], n[2], q[1] * n[2] - q[2] * n[1], q[2] * n[0] - q[0] * n[2],
                                                 q[0] * n[1] - q[1] * n[0]};
                // Huber weight at a tenth of the distance gate, so that wrong pairs pull less.
                const double huber = 0.1 * max_distance;
                const double weight = std::fabs(residual) <= huber ? 1.0 : huber / std::fabs(residual);
                for (int a = 0; a < 6; ++a) {
                    b[a] += weight * j[a] * residual;
                    for (int c = 0; c < 6; ++c) h[a][c] += weight * j[a] * j[c];
                }
                squared_sum += residual * residual;
                ++inliers;
            }
            outcome.hessian = h;
            outcome.inliers = inliers;
            outcome.error = inliers > 0 ? squared_sum / static_cast<double>(inliers) : 0.0;
            if (inliers < static_cast<std::uint64_t>(config.min_inliers)) {
                outcome.failure = "only " + std::to_string(inliers) + " correspondences within " +
                                  std::to_string(max_distance) + " m (need " + std::to_string(config.min_inliers) + ")";
                return outcome;
            }
            std::array<double, 6> eigenvalues{};
            Matrix<6> eigenvectors{};
            symmetric_eigen<6>(h, eigenvalues, eigenvectors);
            if (!(eigenvalues[0] > 1e-9 * eigenvalues[5])) {
                outcome.failure = "degenerate geometry: the Hessian constrains fewer than six degrees of freedom";
                return outcome;
            }
            std::array<double, 6> minus_b{};
            for (int a = 0; a < 6; ++a) minus_b[a] = -b[a];
            std::array<double, 6> step{};
            if (!cholesky_solve(h, minus_b, step)) {
                outcome.failure = "the normal equations are not positive definite";
                return outcome;
            }
            const Matrix<3> delta = rotation_exp({step[3], step[4], step[5]});
            outcome.rotation = orthonormalised(multiply(delta, outcome.rotation));
            Vec3 moved{};
            for (int r = 0; r < 3; ++r) {
                moved[r] = delta[r][0] * outcome.translation[0] + delta[r][1] * outcome.translation[1] +
                           delta[r][2] * outcome.translation[2] + step[r];
            }
            outcome.translation = moved;
            const double translation_step = std::sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]);
            const double rotation_step = std::sqrt(step[3] * step[3] + step[4] * step[4] + step[5] * step[5]);
            if (translation_step < config.translation_eps_m && rotation_step < rotation_eps) {
                stage_converged = true;
                break;
            }
        }
        if (!stage_converged && scale == 1.0) {
            outcome.failure = "not converged after " + std::to_string(config.max_iterations) + " iterations";
            return outcome;
        }
    }
    outcome.converged = true;
    return outcome;
}

// Copies `text` into a host buffer, cut to its capacity.
void write_text(std::uint8_t* buffer, std::size_t capacity, std::size_t* len, const std::string& text) {
    *len = 0;
    if (buffer == nullptr) return;
    const std::size_t n = std::min(capacity, text.size());
    std::memcpy(buffer, text.data(), n);
    *len = n;
}

SkidStatus report(SkidErrorBuf* error, SkidStatus status, const std::string& key, const std::string& message) {
    if (error != nullptr) {
        write_text(error->message, error->message_capacity, &error->message_len, message);
        write_text(error->key, error->key_capacity, &error->key_len, key);
    }
    return status;
}

// Runs `body`, turning every exception into a status and a message for the host.
template <typename Body>
SkidStatus guarded(SkidErrorBuf* error, Body body) {
    try {
        body();
        return SkidStatus_OK;
    } catch (const ConfigError& refused) {
        return report(error, SkidStatus_CONFIG, refused.key, refused.message);
    } catch (const std::bad_alloc&) {
        return report(error, SkidStatus_FAILED, "", "out of memory");
    } catch (const std::invalid_argument& bad) {
        return report(error, SkidStatus_INVALID_ARGUMENT, "", bad.what());
    } catch (const std::exception& failure) {
        return report(error, SkidStatus_FAILED, "", failure.what());
    } catch (...) {
        return report(error, SkidStatus_PANICKED, "", "an unknown C++ exception");
    }
}

SkidAbiStr text(const char* value) {
    return SkidAbiStr{reinterpret_cast<const std::uint8_t*>(value), std::strlen(value)};
}

SkidStatus create(SkidAbiStr config, const SkidHostContext* context, SkidHandle* out_handle, SkidErrorBuf* error) {
    return guarded(error, [&] {
        if (out_handle == nullptr || context == nullptr) throw std::invalid_argument("create: null argument");
        const std::string text(reinterpret_cast<const char*>(config.ptr), config.len);
        *out_handle = new Instance{parse_config(text)};
    });
}

SkidStatus prepare(SkidHandle handle, SkidAbiCloud cloud, SkidHandle* out_prepared, SkidErrorBuf* error) {
    return guarded(error, [&] {
        if (handle == nullptr || out_prepared == nullptr || (cloud.count > 0 && cloud.points == nullptr)) {
            throw std::invalid_argument("prepare: null argument");
        }
        *out_prepared = prepare_cloud(static_cast<Instance*>(handle)->config, cloud.points, cloud.count);
    });
}

SkidStatus prepared_points(SkidHandle prepared, SkidAbiCloud* out_cloud, SkidErrorBuf* error) {
    return guarded(error, [&] {
        if (prepared == nullptr || out_cloud == nullptr) throw std::invalid_argument("prepared_points: null argument");
        const Prepared& kept = *static_cast<const Prepared*>(prepared);
        out_cloud->points = kept.kept.data();
        out_cloud->count = kept.kept.size();
    });
}

SkidStatus refine(SkidHandle handle, SkidHandle target, SkidHandle source, const SkidAbiTransform* guess,
                  SkidFineResult* out, SkidErrorBuf* error) {
    return guarded(error, [&] {
        if (handle == nullptr || target == nullptr || source == nullptr || guess == nullptr || out == nullptr) {
            throw std::invalid_argument("refine: null argument");
        }
        const Prepared& source_cloud = *static_cast<const Prepared*>(source);
        const Outcome outcome = refine_clouds(static_cast<Instance*>(handle)->config, *static_cast<const Prepared*>(target),
                                              source_cloud, *guess);
        for (int r = 0; r < 4; ++r) {
            for (int c = 0; c < 4; ++c) {
                double value = r == 3 ? (c == 3 ? 1.0 : 0.0) : (c == 3 ? outcome.translation[r] : outcome.rotation[r][c]);
                out->target_from_source.matrix[r * 4 + c] = value;
            }
        }
        for (int r = 0; r < 6; ++r) {
            for (int c = 0; c < 6; ++c) out->information[r * 6 + c] = outcome.hessian[r][c];
        }
        out->converged = outcome.converged ? 1u : 0u;
        out->iterations = outcome.iterations;
        out->inlier_count = outcome.inliers;
        out->inlier_ratio = source_cloud.points.empty()
                                ? 0.0
                                : static_cast<double>(outcome.inliers) / static_cast<double>(source_cloud.points.size());
        out->error = outcome.error;
        write_text(out->failure.ptr, out->failure.capacity, &out->failure.len, outcome.failure);
    });
}

SkidStatus destroy_prepared(SkidHandle prepared, SkidErrorBuf* error) {
    return guarded(error, [&] { delete static_cast<Prepared*>(prepared); });
}

SkidStatus destroy(SkidHandle handle, SkidErrorBuf* error) {
    return guarded(error, [&] { delete static_cast<Instance*>(handle); });
}

const SkidFineVTable kTable = {create, prepare, prepared_points, refine, destroy_prepared, destroy};

const SkidPluginDecl kPlugins[] = {
    {SkidSlotKind_FINE, SkidThreading_INDEPENDENT_INSTANCES, text(kName), text(kSummary), text(kDefaultConfig), &kTable},
};

const SkidLibraryDecl kLibrary = {
    SKID_ABI_VERSION,
    0,
    SKID_LAYOUT_FINGERPRINT,
    text(SKID_FRAMEWORK_VERSION),
    text("skid-example-cpp"),
    nullptr,  // No logger: this example reports through its return values only.
    sizeof(kPlugins) / sizeof(kPlugins[0]),
    kPlugins,
};

}  // namespace
}  // namespace skid_example

SKID_EXPORT const SkidLibraryDecl* skid_plugin_entry(void) {
    return &skid_example::kLibrary;
}
