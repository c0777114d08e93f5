//! What the camera looks at: procedural layered scenes with exact flow, test patterns, readers.
