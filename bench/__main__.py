import sys

from boids_env.bench.run import main

sys.exit(main())
