adjustment_0.adj_param_0.center:  0
adjustment_0.adj_param_0.description:  intrack_offset
adjustment_0.adj_param_0.lock_flag:  0
adjustment_0.adj_param_0.parameter:  0
adjustment_0.adj_param_0.sigma:  50
adjustment_0.adj_param_0.units:  pixel
adjustment_0.adj_param_1.center:  0
adjustment_0.adj_param_1.description:  crtrack_offset
adjustment_0.adj_param_1.lock_flag:  0
adjustment_0.adj_param_1.parameter:  0
adjustment_0.adj_param_1.sigma:  50
adjustment_0.adj_param_1.units:  pixel
adjustment_0.adj_param_2.center:  0
adjustment_0.adj_param_2.description:  intrack_scale
adjustment_0.adj_param_2.lock_flag:  0
adjustment_0.adj_param_2.parameter:  0
adjustment_0.adj_param_2.sigma:  50
adjustment_0.adj_param_2.units:  unknown
adjustment_0.adj_param_3.center:  0
adjustment_0.adj_param_3.description:  crtrack_scale
adjustment_0.adj_param_3.lock_flag:  0
adjustment_0.adj_param_3.parameter:  0
adjustment_0.adj_param_3.sigma:  50
adjustment_0.adj_param_3.units:  unknown
adjustment_0.adj_param_4.center:  0
adjustment_0.adj_param_4.description:  map_rotation
adjustment_0.adj_param_4.lock_flag:  0
adjustment_0.adj_param_4.parameter:  0
adjustment_0.adj_param_4.sigma:  0.1
adjustment_0.adj_param_4.units:  degrees
adjustment_0.description:  Initial adjustment
adjustment_0.dirty_flag:  0
adjustment_0.number_of_params:  5
bias_error:  0
ce90_absolute:  0
ce90_relative:  0
current_adjustment:  0
height_off:  1075
height_scale:  885
image_id:  690908101-001
lat_off:  95.0
lat_scale:  0.0989506933075148
line_den_coeff_00:  1
line_den_coeff_01:  0.000313072228965896
line_den_coeff_02:  0.000107317426197985
line_den_coeff_03:  -3.04846904985546e-05
line_den_coeff_04:  -2.15762936983094e-05
line_den_coeff_05:  3.71179957131532e-07
line_den_coeff_06:  -5.0028521513199e-06
line_den_coeff_07:  -2.98336322727379e-05
line_den_coeff_08:  0.000103597971401449
line_den_coeff_09:  -4.77430812255642e-05
line_den_coeff_10:  7.73863099757773e-08
line_den_coeff_11:  -7.55570612493455e-08
line_den_coeff_12:  -2.949850421705e-06
line_den_coeff_13:  -2.97845203603986e-08
line_den_coeff_14:  7.48529215923864e-07
line_den_coeff_15:  9.20914988311729e-08
line_den_coeff_16:  7.52992768825527e-10
line_den_coeff_17:  -5.63049432223841e-09
line_den_coeff_18:  -3.11068697548616e-07
line_den_coeff_19:  2.70651672342708e-09
line_num_coeff_00:  5.26639713844276e-05
line_num_coeff_01:  0.0204059031462319
line_num_coeff_02:  -1.03205102244059
line_num_coeff_03:  0.0120792382802113
line_num_coeff_04:  0.000286367710770682
line_num_coeff_05:  -3.27481431760022e-06
line_num_coeff_06:  -2.91198652317559e-05
line_num_coeff_07:  -0.000875777110286924
line_num_coeff_08:  5.67515076702295e-05
line_num_coeff_09:  -1.35238466137459e-06
line_num_coeff_10:  5.2132899464949e-07
line_num_coeff_11:  -3.53831721034165e-07
line_num_coeff_12:  -2.83687942223826e-05
line_num_coeff_13:  -9.75673635066849e-07
line_num_coeff_14:  3.29218086384635e-05
line_num_coeff_15:  0.000168766927357807
line_num_coeff_16:  4.93235774337535e-05
line_num_coeff_17:  -3.86699910421775e-07
line_num_coeff_18:  -3.57500864877713e-06
line_num_coeff_19:  -5.76181715211193e-07
line_off:  21109.5
line_scale:  21137.5
ll_lat:  44.041491580132
ll_lon:  5.1660942323177
long_off:  5.28464655928485
long_scale:  0.12870115852264
lr_lat:  44.0451195103381
lr_lon:  5.41295839245642
meters_per_pixel_x:  0.506056725316702
meters_per_pixel_y:  0.503974455999626
number_lines:  41801
number_of_adjustments:  1
number_samples:  39182
polynomial_format:  B
rand_error:  0
rect:  0 0 39181 41800
ref_point_hgt:  1075
ref_point_lat:  44.1381638226809
ref_point_line:  20900
ref_point_lon:  5.28759198209756
ref_point_samp:  19590.5
samp_den_coeff_00:  1
samp_den_coeff_01:  0.00184583711996889
samp_den_coeff_02:  0.00100395951131101
samp_den_coeff_03:  -0.00071717314331181
samp_den_coeff_04:  -3.52199407939995e-05
samp_den_coeff_05:  -1.5199277123018e-07
samp_den_coeff_06:  -6.23472184864609e-08
samp_den_coeff_07:  7.19962145018582e-06
samp_den_coeff_08:  3.87426734509274e-06
samp_den_coeff_09:  -5.07374260133059e-06
samp_den_coeff_10:  -1.05883597054374e-07
samp_den_coeff_11:  -1.66834227904931e-08
samp_den_coeff_12:  7.69789979382629e-07
samp_den_coeff_13:  4.71748046536882e-10
samp_den_coeff_14:  -1.79224911577728e-07
samp_den_coeff_15:  -6.94415912245717e-07
samp_den_coeff_16:  -9.75936192802885e-09
samp_den_coeff_17:  1.59322482156146e-08
samp_den_coeff_18:  8.38803634249434e-08
samp_den_coeff_19:  5.90483872722103e-09
samp_num_coeff_00:  -0.0043183317882885
samp_num_coeff_01:  1.01915446681969
samp_num_coeff_02:  0.0168055138420769
samp_num_coeff_03:  -0.00348140487613588
samp_num_coeff_04:  -0.000916661398454011
samp_num_coeff_05:  0.000695425314713826
samp_num_coeff_06:  -0.000384942875908067
samp_num_coeff_07:  0.00252455837541622
samp_num_coeff_08:  9.43366681802647e-05
samp_num_coeff_09:  2.72800205000598e-06
samp_num_coeff_10:  -1.07644697154364e-06
samp_num_coeff_11:  -5.58776794164766e-06
samp_num_coeff_12:  -5.07570019092412e-06
samp_num_coeff_13:  -4.38323738745708e-06
samp_num_coeff_14:  2.94927767731348e-05
samp_num_coeff_15:  -0.00018700584391133
samp_num_coeff_16:  -3.86983463096798e-07
samp_num_coeff_17:  2.62127978818087e-06
samp_num_coeff_18:  6.48307226373421e-06
samp_num_coeff_19:  1.74530251839139e-08
samp_off:  19207.5
samp_scale:  19999.5
sensor:  PHR 1B
support_data.across_track_incidence_angle:  """2.5160109830115 2.27779853983972 2.03320008516263 """
support_data.along_track_incidence_angle:  """-8.24621807083902 -8.2801983023842 -8.31535510181351 """
support_data.azimuth_angle:  """149.028155144455 148.949703698798 148.870814354145 """
support_data.band_name_list:  """P """
support_data.elevation_angle:  """59.7532369186131 59.8333141632861 59.913285412915 """
support_data.image_date:  2013-08-05T10:42:19.4Z
support_data.image_id:  690908101-001
support_data.image_size:  39182 41801
support_data.incident_angle:  """8.61147426563896 8.57945974242188 8.55360640150574 """
support_data.instrument:  PHR
support_data.instrument_index:  1B
support_data.line_period:  0.0735
support_data.ll_ground_point:  44.0404482970177 5.16561275895156 0 WGE
support_data.lr_ground_point:  44.0451107179172 5.41295687669197 0 WGE
support_data.number_bands:  1
support_data.number_of_across_track_incidence_angle:  3
support_data.number_of_along_track_incidence_angle:  3
support_data.number_of_azimuth_angle:  3
support_data.number_of_elevation_angle:  3
support_data.number_of_incident_angle:  3
support_data.number_of_scene_orientation:  3
support_data.number_of_viewing_angle:  3
support_data.physical_bias:  """0 """
support_data.physical_gain:  """12.04 """
support_data.processing_level:  SENSOR
support_data.production_date:  2013-10-21T15:47:55.345
support_data.reference_ground_point:  44.1375906346513 5.28725350787555 0 WGE
support_data.reference_image_point:  19591 20900.5
support_data.scene_orientation:  """179.119257371103 179.112642602051 179.148779792784 """
support_data.sensorID:  PHR 1B
support_data.solar_irradiance:  """1548 """
support_data.swath_first_col:  793
support_data.swath_last_col:  39974
support_data.time_range_end:  2013-08-05T10:42:22.5693580Z
support_data.time_range_start:  2013-08-05T10:42:19.4970580Z
support_data.type:  ossimPleiadesDimapSupportData
support_data.ul_ground_point:  44.2299682087566 5.16105749217467 0 WGE
support_data.ur_ground_point:  44.2348353149138 5.40938690368401 0 WGE
support_data.viewing_angle:  """7.91628114788844 7.8887518078899 7.86663733940663 """
type:  ossimPleiadesModel
ul_lat:  44.2309607575797
ul_lon:  5.16160440951187
ur_lat:  44.2348283084732
ur_lon:  5.40938637216026
