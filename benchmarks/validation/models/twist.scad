// twisted prism: a hexagon 22 mm across its corners, turned 90 degrees over 14 mm of height
linear_extrude(height = 14, twist = 90, slices = 40) circle(r = 11, $fn = 6);
