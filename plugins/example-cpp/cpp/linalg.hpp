// Small dense linear algebra for the example plugin: symmetric eigen-decomposition by cyclic Jacobi
// rotations (3x3 for normals, 6x6 for the Hessian's conditioning), Cholesky solves of the 6x6 normal
// equations, and the rotation exponential (Rodrigues' formula).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>

namespace skid_example {

template <std::size_t N>
using Matrix = std::array<std::array<double, N>, N>;

// Eigenvalues of the symmetric matrix `a` (ascending, in `values`) and the matching unit eigenvectors
// (the columns of `vectors`). `a` is taken by value and destroyed.
template <std::size_t N>
void symmetric_eigen(Matrix<N> a, std::array<double, N>& values, Matrix<N>& vectors) {
    for (std::size_t i = 0; i < N; ++i) {
        for (std::size_t j = 0; j < N; ++j) vectors[i][j] = i == j ? 1.0 : 0.0;
    }
    for (int sweep = 0; sweep < 64; ++sweep) {
        double off = 0.0;
        for (std::size_t p = 0; p < N; ++p) {
            for (std::size_t q = p + 1; q < N; ++q) off += a[p][q] * a[p][q];
        }
        if (off < 1e-30) break;
        for (std::size_t p = 0; p < N; ++p) {
            for (std::size_t q = p + 1; q < N; ++q) {
                if (std::fabs(a[p][q]) < 1e-300) continue;
                const double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                const double t = (theta >= 0.0 ? 1.0 : -1.0) / (std::fabs(theta) + std::sqrt(theta * theta + 1.0));
                const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
                for (std::size_t k = 0; k < N; ++k) {
                    const double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (std::size_t k = 0; k < N; ++k) {
                    const double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for (std::size_t k = 0; k < N; ++k) {
                    const double vkp = vectors[k][p], vkq = vectors[k][q];
                    vectors[k][p] = c * vkp - s * vkq;
                    vectors[k][q] = s * vkp + c * vkq;
                }
            }
        }
    }
    for (std::size_t i = 0; i < N; ++i) values[i] = a[i][i];
    // Sort ascending, moving the eigenvectors along.
    for (std::size_t i = 0; i < N; ++i) {
        for (std::size_t j = i + 1; j < N; ++j) {
            if (values[j] < values[i]) {
                std::swap(values[i], values[j]);
                for (std::size_t k = 0; k < N; ++k) std::swap(vectors[k][i], vectors[k][j]);
            }
        }
    }
}

// Solves h x = rhs for a symmetric positive definite h by Cholesky; false when h is not.
inline bool cholesky_solve(const Matrix<6>& h, const std::array<double, 6>& rhs, std::array<double, 6>& x) {
    Matrix<6> l{};
    for (std::size_t i = 0; i < 6; ++i) {
        for (std::size_t j = 0; j <= i; ++j) {
            double sum = h[i][j];
            for (std::size_t k = 0; k < j; ++k) sum -= l[i][k] * l[j][k];
            if (i == j) {
                if (!(sum > 0.0)) return false;
                l[i][i] = std::sqrt(sum);
            } else {
                l[i][j] = sum / l[j][j];
            }
        }
    }
    std::array<double, 6> y{};
    for (std::size_t i = 0; i < 6; ++i) {
        double sum = rhs[i];
        for (std::size_t k = 0; k < i; ++k) sum -= l[i][k] * y[k];
        y[i] = sum / l[i][i];
    }
    for (std::size_t i = 6; i-- > 0;) {
        double sum = y[i];
        for (std::size_t k = i + 1; k < 6; ++k) sum -= l[k][i] * x[k];
        x[i] = sum / l[i][i];
    }
    return true;
}

// The rotation matrix of the rotation vector `w` (axis times angle in radians).
inline Matrix<3> rotation_exp(const std::array<double, 3>& w) {
    const double angle = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    Matrix<3> r{};
    if (angle < 1e-12) {
        r = {{{1.0, -w[2], w[1]}, {w[2], 1.0, -w[0]}, {-w[1], w[0], 1.0}}};
        return r;
    }
    const double x = w[0] / angle, y = w[1] / angle, z = w[2] / angle;
    const double c = std::cos(angle), s = std::sin(angle), v = 1.0 - c;
    r = {{{c + x * x * v, x * y * v - z * s, x * z * v + y * s},
          {y * x * v + z * s, c + y * y * v, y * z * v - x * s},
          {z * x * v - y * s, z * y * v + x * s, c + z * z * v}}};
    return r;
}

inline Matrix<3> multiply(const Matrix<3>& a, const Matrix<3>& b) {
    Matrix<3> c{};
    for (std::size_t i = 0; i < 3; ++i) {
        for (std::size_t j = 0; j < 3; ++j) {
            for (std::size_t k = 0; k < 3; ++k) c[i][j] += a[i][k] * b[k][j];
        }
    }
    return c;
}

// The nearest rotation to `r` by Gram-Schmidt on its columns (removes drift from repeated products).
inline Matrix<3> orthonormalised(const Matrix<3>& r) {
    std::array<std::array<double, 3>, 3> columns{};
    for (std::size_t c = 0; c < 3; ++c) {
        for (std::size_t i = 0; i < 3; ++i) columns[c][i] = r[i][c];
    }
    auto normalise = [](std::array<double, 3>& v) {
        const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (double& x : v) x /= n;
    };
    auto dot = [](const std::array<double, 3>& a, const std::array<double, 3>& b) {
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    };
    normalise(columns[0]);
    const double d01 = dot(columns[0], columns[1]);
    for (std::size_t i = 0; i < 3; ++i) columns[1][i] -= d01 * columns[0][i];
    normalise(columns[1]);
    columns[2] = {columns[0][1] * columns[1][2] - columns[0][2] * columns[1][1],
                  columns[0][2] * columns[1][0] - columns[0][0] * columns[1][2],
                  columns[0][0] * columns[1][1] - columns[0][1] * columns[1][0]};
    Matrix<3> out{};
    for (std::size_t c = 0; c < 3; ++c) {
        for (std::size_t i = 0; i < 3; ++i) out[i][c] = columns[c][i];
    }
    return out;
}

}  // namespace skid_example
