import pytest


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """The trainer's tests run small nets on a shared 2-core machine, where one torch thread is
    faster; the thread count is restored afterwards."""
    import torch

    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)
