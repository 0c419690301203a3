"""Numbers the papers report, quoted so that notebooks can print them beside ours.

Only quotations live here (never results of ours).  Paper 001: L. De Vito, G. Mazzilli,
M. Riccio, C. Sementa, "Improving the orientation estimation in a packet loss-affected
wireless sensor network for tracking human motion", Section II.  Paper 002: M. Giuberti, M. Martalò,
G. Ferrari, "A hybrid radio/accelerometric approach to arm posture recognition", Tables 2
and 3 and Section 5 (position errors in cm).
"""

from __future__ import annotations

import pandas as pd

#: Paper 001, Section II (Fig. 3): maximum humerus pitch error (°) of each estimator.
PAPER001_SECTION2_MAX_ERROR_DEG = {"single frame": 8.5, "data fusion": 14.9}

#: Paper 001, Section IV (Figs. 6 and 8, stated in words) after its 4-packet loss: data fusion
#: deviates for more than 2 s; the hybrid stays around 10° for about 1 s.
PAPER001_SECTION4_AFTER_LOSS = {"data fusion": {"words": "deviates for > 2 s", "error_deg": None, "duration_s": 2.0},
                                "hybrid": {"words": "≈ 10° for ≈ 1 s", "error_deg": 10.0, "duration_s": 1.0}}

#: Paper 002, Section 5 (static conditions): average position error (cm) of each approach.
PAPER002_STATIC_PE_CM = {"deterministic": 3.0, "probabilistic": 4.8}

#: Table 2 of paper 002: PE (cm) per target and movement, deterministic, probabilistic, Kinect.
PAPER002_TABLE2_PE_CM = pd.DataFrame(
    {
        "target": [1] * 8 + [2] * 8,
        "movement": list(range(1, 9)) * 2,
        "deterministic": [1.2, 4, 1.3, 4.5, 1.3, 4.2, 0.4, 4.4, 3.3, 15, 3.6, 12.5, 3.6, 13.9, 1.2, 12.7],
        "probabilistic": [2.6, 6.7, 1.3, 7.4, 3.4, 6.3, 0.4, 6.3, 10.7, 21.9, 4.5, 19.9, 9.4, 22.8, 2.4, 15.1],
        "kinect": [8.4, 7.1, 7.5, 11.4, 8.1, 6.9, 7.8, 7.7, 18.1, 12, 15.6, 25.9, 17.2, 12.5, 17.1, 17.6],
    }
).set_index(["target", "movement"])

#: Table 2's last row: average PE (cm) over both targets and all movements.
PAPER002_TABLE2_AVERAGE_CM = {"deterministic": 5.4, "probabilistic": 8.8, "kinect": 12.6}

#: Table 3 of paper 002: PE (cm) per target with one setting for all movements.
PAPER002_TABLE3_PE_CM = pd.DataFrame(
    {"target": [1, 2], "deterministic": [4.2, 14], "probabilistic": [6.1, 17.9], "kinect": [8.1, 17.1]}
).set_index("target")

#: Table 3's last row: average PE (cm).
PAPER002_TABLE3_AVERAGE_CM = {"deterministic": 9.1, "probabilistic": 12.0, "kinect": 12.6}

#: The deployable union of Table 3's optimal anchor subsets that the paper derives (Section 5).
PAPER002_DEPLOYABLE_DETERMINISTIC = "{2, 3, 5, 6, 7}"
