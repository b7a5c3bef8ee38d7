import warnings

import pytest
import warp as wp

wp.config.quiet = True
warnings.filterwarnings("ignore", message=".*CUDA.*")


@pytest.fixture(scope="session", autouse=True)
def _warp_initialized():
    wp.init()
