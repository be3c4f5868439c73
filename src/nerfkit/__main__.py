import sys

from nerfkit.cli.main import main

sys.exit(main())
