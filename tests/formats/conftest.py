from pathlib import Path

import pytest

# The shared data folder sits next to the checkout (/work/main -> /work/shared); a worktree
# one level deeper (/work/wt/formats) finds it one more level up.
_HERE = Path(__file__).resolve()
_CANDIDATES = [_HERE.parents[2].parent / "shared/data/list1.4607",
               _HERE.parents[2].parent.parent / "shared/data/list1.4607"]
LIST1 = next((p for p in _CANDIDATES if p.exists()), _CANDIDATES[0])


@pytest.fixture
def list1_path():
    if not LIST1.exists():
        pytest.skip(f"real 4607 sample not found at {LIST1} (a copy of pentlandedge/s4607_extra "
                    "test/list1.4607 that lives in the shared data folder next to the checkout)")
    return LIST1
