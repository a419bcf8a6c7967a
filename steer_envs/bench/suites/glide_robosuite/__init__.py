"""GLiDE on the robosuite arms (thesis §4.4): replay data, mode grounding (Table 4.2), policies (Table 4.3)."""
