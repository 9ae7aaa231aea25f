// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// A small consumer of the umbrella header: voxel grid, HDBSCAN and the dynamic-feature filter on
// Eigen matrices that a peer library (eigen_peer, other compiler flags) allocates and frees.
#include <cstdio>

#include <ds3d/ds3d.hpp>

#include "eigen_peer.hpp"

int main() {
  // Two blobs of 200 points each, allocated by the peer library.
  const ds3d::Points3f cloud = eigen_peer::make_blobs(200, 7);
  const ds3d::VoxelGridResult vg = ds3d::voxel_grid(cloud, {.leaf_size = 0.01F});
  const ds3d::HdbscanResult hd =
      ds3d::hdbscan(vg.centroids.cast<double>(), {.min_cluster_size = 10});
  int clusters = 0;
  for (const std::int32_t label : hd.labels) clusters = label + 1 > clusters ? label + 1 : clusters;

  // Keypoints on a person standing 2 m away inside a box, plus background keypoints at 4 m.
  ds3d::Keypoints3f kp = eigen_peer::make_keypoints(300, 11);  // allocated by the peer
  ds3d::PinholeCamera cam;
  ds3d::ImageBox box;
  box.x_min = 200, box.y_min = 100, box.x_max = 300, box.y_max = 400, box.score = 0.9F;
  ds3d::DynamicFeatureFilter filter;
  const ds3d::DynamicFilterResult r = filter.filter(kp, {box}, cam);
  kp.conservativeResize(kp.rows() / 2, 3);  // reallocated here, freed by the peer below
  const double peer_sum = eigen_peer::consume(std::move(kp));

  std::printf("umbrella_app: %zu voxels, %d clusters, %d of 300 keypoints dynamic, peer %.1f\n",
              static_cast<std::size_t>(vg.centroids.rows()), clusters, r.num_dynamic, peer_sum);
  const bool ok = vg.centroids.rows() > 0 && clusters == 2 && r.num_dynamic >= 100 &&
                  r.num_dynamic <= 200 && peer_sum > 0.0;
  std::puts(ok ? "umbrella_app: OK" : "umbrella_app: FAILED");
  return ok ? 0 : 1;
}
