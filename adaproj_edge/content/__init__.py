"""Content: images, user masks, saliency and the content map the warp weighs."""
