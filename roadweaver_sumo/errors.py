"""The one exception type the command line turns into a one-line error and a non-zero exit."""


class RoadweaverError(Exception):
    """A problem the user can act on: bad input, a failed external tool, a failed scenario.

    The message is a single line that names the problem; the CLI prints it as
    ``roadweaver-sumo: error: <message>`` without a traceback.
    """
