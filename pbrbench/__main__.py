import sys

from pbrbench.cli.main import main

sys.exit(main())
