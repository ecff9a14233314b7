import sys

from mimicrete.cli import main

sys.exit(main())
