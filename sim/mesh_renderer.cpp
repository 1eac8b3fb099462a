#include "sim/mesh_renderer.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace lipdrive {
namespace {

const cv::Vec3f kSkinBgr{140, 170, 215};
const cv::Vec3f kInsideBgr{20, 16, 40};  // back faces: the mouth cavity reads as dark
constexpr float kAmbient = 0.25f;

/// Area-weighted vertex normals in view space (unnormalised sums of face normals),
/// from the faces turned towards the camera only: where the skin meets the inside
/// of the mouth, the inside must not darken the lips.
Eigen::Matrix3Xf vertex_normals(const Eigen::Matrix3Xf& view_vertices, const std::vector<Triangle>& triangles) {
  Eigen::Matrix3Xf normals = Eigen::Matrix3Xf::Zero(3, view_vertices.cols());
  for (const Triangle& t : triangles) {
    const Eigen::Vector3f a = view_vertices.col(t[0]), b = view_vertices.col(t[1]), c = view_vertices.col(t[2]);
    const Eigen::Vector3f n = (b - a).cross(c - a);
    if (n.z() <= 0) continue;
    for (std::uint32_t v : t) normals.col(v) += n;
  }
  return normals;
}

/// Twice the signed area of (a, b, p) in pixel space: the edge function of a rasteriser.
float edge(const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& p) {
  return (b.x() - a.x()) * (p.y() - a.y()) - (b.y() - a.y()) * (p.x() - a.x());
}

}  // namespace

Eigen::Vector2f ImageProjection::project(const Eigen::Vector3f& vertex) const {
  const Eigen::Vector3f v = rotation * vertex;
  return {offset.x() + scale * v.x(), offset.y() - scale * v.y()};
}

float ImageProjection::depth(const Eigen::Vector3f& vertex) const { return (rotation * vertex).z(); }

ImageProjection fit_projection(const Eigen::Matrix3Xf& vertices, const RenderView& view) {
  if (vertices.cols() == 0) throw std::invalid_argument("fit_projection: the mesh has no vertices");
  ImageProjection p;
  p.rotation = Eigen::AngleAxisf(view.yaw_degrees * std::numbers::pi_v<float> / 180, Eigen::Vector3f::UnitY())
                   .toRotationMatrix();
  const Eigen::Matrix3Xf rotated = p.rotation * vertices;
  const Eigen::Vector2f lo = rotated.topRows<2>().rowwise().minCoeff();
  const Eigen::Vector2f hi = rotated.topRows<2>().rowwise().maxCoeff();
  const Eigen::Vector2f extent = (hi - lo).cwiseMax(1e-6f);
  const float usable = 1 - 2 * view.margin;
  p.scale = std::min(usable * view.size.width / extent.x(), usable * view.size.height / extent.y());
  const Eigen::Vector2f centre = (lo + hi) / 2;
  p.offset = {view.size.width / 2.0f - p.scale * centre.x(), view.size.height / 2.0f + p.scale * centre.y()};
  return p;
}

ImageProjection camera_projection(const Eigen::Matrix<double, 3, 4>& camera) {
  // ImageProjection's y axis points up: its second row is the camera's negated.
  Eigen::Matrix<double, 2, 3> rows = camera.topLeftCorner<2, 3>();
  rows.row(1) *= -1;
  const Eigen::JacobiSVD<Eigen::Matrix<double, 2, 3>> svd(rows, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix<double, 2, 3> orthonormal = svd.matrixU() * svd.matrixV().leftCols<2>().transpose();
  ImageProjection p;
  p.rotation.row(0) = orthonormal.row(0).cast<float>();
  p.rotation.row(1) = orthonormal.row(1).cast<float>();
  p.rotation.row(2) = p.rotation.row(0).cross(p.rotation.row(1));
  p.scale = static_cast<float>(svd.singularValues().mean());
  p.offset = camera.block<2, 1>(0, 3).cast<float>();
  return p;
}

cv::Mat render_mesh(const Mesh& mesh, const RenderView& view) {
  return render_mesh(mesh, view.size, fit_projection(mesh.vertices, view));
}

cv::Mat render_mesh(const Mesh& mesh, const cv::Size& size, const ImageProjection& projection) {
  const Eigen::Matrix3Xf view_vertices = projection.rotation * mesh.vertices;
  const Eigen::Matrix3Xf normals = vertex_normals(view_vertices, mesh.triangles);
  const Eigen::Vector3f light = Eigen::Vector3f(-0.35f, 0.45f, 1).normalized();

  // Lambert intensity per vertex, interpolated across each triangle (Gouraud).
  std::vector<float> intensity(static_cast<std::size_t>(mesh.vertices.cols()));
  for (Eigen::Index v = 0; v < mesh.vertices.cols(); ++v) {
    const float norm = normals.col(v).norm();
    const float lambert = norm > 0 ? std::max(0.0f, normals.col(v).dot(light) / norm) : 0;
    intensity[static_cast<std::size_t>(v)] = kAmbient + (1 - kAmbient) * lambert;
  }

  cv::Mat image(size, CV_8UC3, cv::Scalar::all(0));
  cv::Mat depth(size, CV_32F, cv::Scalar::all(-std::numeric_limits<float>::infinity()));
  for (const Triangle& t : mesh.triangles) {
    const Eigen::Vector3f a = view_vertices.col(t[0]), b = view_vertices.col(t[1]), c = view_vertices.col(t[2]);
    const bool front = (b - a).cross(c - a).z() > 0;  // the camera looks down -z
    const Eigen::Vector2f p0 = projection.project(mesh.vertices.col(t[0]));
    const Eigen::Vector2f p1 = projection.project(mesh.vertices.col(t[1]));
    const Eigen::Vector2f p2 = projection.project(mesh.vertices.col(t[2]));
    const float area = edge(p0, p1, p2);
    if (std::abs(area) < 1e-9f) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({p0.x(), p1.x(), p2.x()}))));
    const int x1 = std::min(size.width - 1, static_cast<int>(std::ceil(std::max({p0.x(), p1.x(), p2.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({p0.y(), p1.y(), p2.y()}))));
    const int y1 = std::min(size.height - 1, static_cast<int>(std::ceil(std::max({p0.y(), p1.y(), p2.y()}))));
    for (int y = y0; y <= y1; ++y) {
      auto* depth_row = depth.ptr<float>(y);
      auto* image_row = image.ptr<cv::Vec3b>(y);
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2f p{x + 0.5f, y + 0.5f};
        const float w0 = edge(p1, p2, p) / area, w1 = edge(p2, p0, p) / area, w2 = edge(p0, p1, p) / area;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = w0 * a.z() + w1 * b.z() + w2 * c.z();
        if (z <= depth_row[x]) continue;
        depth_row[x] = z;
        const float shade = w0 * intensity[t[0]] + w1 * intensity[t[1]] + w2 * intensity[t[2]];
        image_row[x] = front ? cv::Vec3b(kSkinBgr * shade) : cv::Vec3b(kInsideBgr);
      }
    }
  }
  return image;
}

}  // namespace lipdrive
