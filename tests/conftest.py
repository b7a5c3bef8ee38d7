import warnings

import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no kernel-cache chatter in test output
warnings.filterwarnings("ignore", message=".*CUDA.*")


@pytest.fixture(scope="session", autouse=True)
def _warp_initialized():
    wp.init()


def pytest_configure(config):
    import assets  # noqa: F401  (tests/assets: a usage error if PBRWARP_TEST_ASSETS names no asset folder)


def pytest_report_header(config):
    import assets

    return assets.describe()
