"""Classic benchmark functions, vectorised over a population (rows = candidates).

Used by the optimizer tests and the comparison with mealpy; bounds are the customary ones.
"""

import numpy as np


def sphere(X: np.ndarray) -> np.ndarray:
    X = np.atleast_2d(X)
    return np.sum(X * X, axis=1)


def rosenbrock(X: np.ndarray) -> np.ndarray:
    X = np.atleast_2d(X)
    return np.sum(100.0 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1.0 - X[:, :-1]) ** 2, axis=1)


def rastrigin(X: np.ndarray) -> np.ndarray:
    X = np.atleast_2d(X)
    return 10.0 * X.shape[1] + np.sum(X * X - 10.0 * np.cos(2.0 * np.pi * X), axis=1)


FUNCTIONS = {
    # name: (function, lower bound, upper bound) per dimension
    "sphere": (sphere, -100.0, 100.0),
    "rosenbrock": (rosenbrock, -30.0, 30.0),
    "rastrigin": (rastrigin, -5.12, 5.12),
}
