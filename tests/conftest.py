import warnings

import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no kernel-cache chatter in test output
warnings.filterwarnings("ignore", message=".*CUDA.*")


@pytest.fixture(scope="session", autouse=True)
def _warp_initialized():
    wp.init()
