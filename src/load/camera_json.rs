//! `camera.json` beside a scene file (stub, replaced by the full reader).
