#pragma once
// Anderson's acceleration of a fixed-point iteration u <- u + r(u) (type II; Walker & Ni 2011):
// the next point mixes the last iterates' images, with the weights whose mix of their steps is
// smallest in the least-squares sense. A linearly converging iteration (a chord method: the
// same factorised matrix at every step) takes several times fewer steps so; the fixed point is
// the same. Used by the planning model's equilibrium.

#include <Eigen/Dense>
#include <vector>

namespace incise {

/// Anderson mixing over the last `depth` steps; depth 0 is the plain iteration. One owner.
class AndersonMixing {
 public:
  /// Mixes over the last `depth` differences of steps (0: none).
  explicit AndersonMixing(int depth) : depth_(depth) {}

  /// The next point after `u`, whose step is `r` (the plain iteration would go to u + r).
  [[nodiscard]] Eigen::VectorXd next(const Eigen::VectorXd& u, const Eigen::VectorXd& r) {
    const Eigen::VectorXd image = u + r;
    if (depth_ <= 0) {
      return image;
    }
    if (have_last_) {
      image_changes_.push_back(image - last_image_);
      step_changes_.push_back(r - last_step_);
      if (static_cast<int>(step_changes_.size()) > depth_) {
        image_changes_.erase(image_changes_.begin());
        step_changes_.erase(step_changes_.begin());
      }
    }
    last_image_ = image;
    last_step_ = r;
    have_last_ = true;
    if (step_changes_.empty()) {
      return image;
    }
    const auto m = static_cast<Eigen::Index>(step_changes_.size());
    Eigen::MatrixXd steps(r.size(), m);
    Eigen::MatrixXd images(r.size(), m);
    for (Eigen::Index j = 0; j < m; ++j) {
      steps.col(j) = step_changes_[static_cast<std::size_t>(j)];
      images.col(j) = image_changes_[static_cast<std::size_t>(j)];
    }
    const Eigen::VectorXd weights = steps.colPivHouseholderQr().solve(r);
    if (!weights.allFinite()) {
      restart();
      return image;
    }
    return image - images * weights;
  }

  /// Forgets the history (the iteration map changed, or a mixed step made things worse): the
  /// next step is the plain iteration's.
  void restart() {
    image_changes_.clear();
    step_changes_.clear();
    have_last_ = false;
  }

 private:
  int depth_;
  bool have_last_ = false;
  Eigen::VectorXd last_image_;
  Eigen::VectorXd last_step_;
  std::vector<Eigen::VectorXd> image_changes_;
  std::vector<Eigen::VectorXd> step_changes_;
};

}  // namespace incise
