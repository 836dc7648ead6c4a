"""Type stubs for the quarry extension module."""
import numpy as np
import numpy.typing as npt

class KalmanFilter:
    """A linear Kalman filter holding x, P and the model (F, Q, H, R); float64 arrays."""

    def __init__(
        self,
        x: npt.NDArray[np.float64],
        P: npt.NDArray[np.float64],
        F: npt.NDArray[np.float64],
        Q: npt.NDArray[np.float64],
        H: npt.NDArray[np.float64],
        R: npt.NDArray[np.float64],
    ) -> None: ...
    def predict(self) -> None:
        """x = F x, P = F P F' + Q."""
    def update(self, z: npt.NDArray[np.float64]) -> None:
        """Update with z of shape (m,) (Joseph form, as filterpy)."""
    def step(self, z: npt.NDArray[np.float64]) -> None:
        """predict() then update(z)."""
    def filter_sequence(self, zs: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Filter a (T, m) measurement array; returns the (T, n) posterior means."""
    @property
    def x(self) -> npt.NDArray[np.float64]: ...
    @property
    def P(self) -> npt.NDArray[np.float64]: ...
