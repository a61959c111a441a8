import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / "conf" / "design" / "baseline.yaml"
sys.path.insert(0, str(Path(__file__).parent))
