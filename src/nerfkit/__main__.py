from nerfkit.cli.entry import command_line

command_line()
