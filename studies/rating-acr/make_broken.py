"""Writes broken.png, the rating example's catch trial: an obviously broken image (random
colour blocks, 800 x 600 like the study's stimuli), which every attentive participant rates
"Bad". Seeded, so it is the same image each time. Needs Pillow (tested with 13.0.0)."""
import random

from PIL import Image

random.seed(49)
small = Image.new("RGB", (25, 19))
small.putdata([tuple(random.randrange(256) for _ in range(3)) for _ in range(25 * 19)])
small.resize((800, 600), Image.NEAREST).save("broken.png", optimize=True)
