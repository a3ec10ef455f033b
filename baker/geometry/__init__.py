"""Pure numpy math: conventions, quaternions and TRS, two-bone IK. No baker types here."""
