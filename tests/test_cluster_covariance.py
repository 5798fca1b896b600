"""The cluster-robust (sandwich) covariance of a least-squares fit, against its definition."""
import numpy as np

from twin.fit.objective import cluster_covariance


def test_the_sandwich_covariance_sums_each_windows_score_before_squaring():
    rng = np.random.default_rng(7)
    J, r = rng.normal(size=(60, 3)), rng.normal(size=60)
    clusters = np.repeat(np.arange(12), 5)  # windows of five residuals each
    prior = np.diag([0.5, 0.0, 2.0])
    bread = np.linalg.inv(J.T @ J + prior.T @ prior)
    meat = sum(np.outer(J[clusters == w].T @ r[clusters == w], J[clusters == w].T @ r[clusters == w])
               for w in range(12)) + prior.T @ prior
    assert np.allclose(cluster_covariance(J, r, clusters, prior), bread @ meat @ bread, rtol=1e-12, atol=0)
    # residuals of one window add before squaring: a cluster per residual is another estimate
    alone = cluster_covariance(J, r, np.arange(60))
    assert not np.allclose(alone, cluster_covariance(J, r, clusters))
    # a Jacobian without information is refused rather than inverted
    assert cluster_covariance(np.zeros((10, 2)), np.ones(10), np.arange(10)) is None
